"""README.md and docs/*.md are guides for users: no commit hash, date or UTC time, no host
note, issue number or path of a developer's machine or outside the repository (history is in
CHANGELOG.md and git log; the figures' commit and date only in docs/figures/*.json), and
within their line budgets. docs/service.md ends with the table of what rigd does when things
go wrong, and every test it names exists."""

import re

import pytest
from testpaths import ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

# a commit hash: 7-40 lower-case hex characters with at least one digit and one letter
HASH = re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d(?:\b|T)|\bUTC\b")
HOST_NOTE = re.compile(r"otherwise idle|idle machine|machine idle|machine was idle|shared VM|"
                       r"build VM|shared 2-core|load average \d|at load \d", re.I)
ISSUE = re.compile(r"\bissues? \d+|\(#\d+\)", re.I)
OUTSIDE = re.compile(r"\.\./shared|/work/|/home/\w|/root/|/Users/\w|C:\\\\")
LIMITS = {"README.md": 150, "diagnose.md": 400, "service.md": 400}


def _hits(pattern, text):
    return [f"line {text.count(chr(10), 0, m.start()) + 1}: {m.group(0)!r}"
            for m in pattern.finditer(text)]


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_page_has_no_history_host_notes_or_outside_paths(page):
    text = page.read_text()
    bad = (_hits(OUTSIDE, text) + _hits(ISSUE, text) + _hits(HASH, text)
           + _hits(DATE, text) + _hits(HOST_NOTE, text))
    assert not bad, f"{page.relative_to(ROOT)}: " + "; ".join(bad[:20])


@pytest.mark.parametrize("name, limit", sorted(LIMITS.items()))
def test_line_budgets(name, limit):
    path = ROOT / name if name == "README.md" else ROOT / "docs" / name
    n = len(path.read_text().splitlines())
    assert n <= limit, f"{name}: {n} lines (at most {limit})"


def test_the_rules_catch_what_they_are_for():
    assert HASH.search("measured on 24803a7") and not HASH.search("feedback deadbeef 0x1021")
    assert DATE.search("2026-11-27 at 09:20 UTC") and DATE.search("on 2026-11-27")
    assert DATE.search("created: '2026-11-22T03:40:00Z'")
    assert HOST_NOTE.search("machine otherwise idle") and ISSUE.search("(issue 21)")
    assert OUTSIDE.search("../shared/data/x.csv") and OUTSIDE.search("Run from /work/main")
    assert not OUTSIDE.search("rigd run --socket /tmp/rigd.sock")


def test_service_md_ends_with_what_happens_when():
    text = (ROOT / "docs" / "service.md").read_text()
    head = "## What happens when…"
    assert head in text, head
    last = text[text.rindex("\n## ") + 1:]
    assert last.startswith(head), "the section must be the page's last"
    rows = [ln for ln in last.splitlines() if ln.startswith("|")]
    assert rows[0] == "| situation | what rigd does | test |" and rows[1] == "|---|---|---|"
    assert len(rows) >= 8
    for row in rows[2:]:
        cells = [c.strip() for c in row.strip("|").split(" | ")]
        assert len(cells) == 3 and all(cells), row
        # every test named exists: the file (a path under tests/), and the function after ::
        current = None
        refs = [r for r in re.findall(r"`([^`]+)`", cells[2])
                if r.startswith(("tests/", "::"))]
        assert refs or "make " in cells[2], f"no test named for: {cells[0]}"
        for ref in refs:
            path, _, func = ref.partition("::")
            if path:
                current = ROOT / path
                assert current.exists(), f"{path} (named in: {cells[0]})"
            if func and current is not None and current.is_file():
                assert f"def {func}(" in current.read_text(), f"{ref} (in: {cells[0]})"
