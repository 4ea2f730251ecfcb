"""Figures are artefacts: docs/figures.md and the README's figures table are what
`python -m tools.figures` renders from the committed docs/figures/*.json (rendered in memory
and compared), each artefact says where it was measured, and a changed figure shows up as a
stale page. No figure is compared with a number of an earlier run."""

import json
import re
import shutil
import subprocess
import sys

import pytest
from testpaths import ROOT

from tools.figures import FIGURES_DIR, FIGURES_MD, README, artefact, pages
from tools.figures.__main__ import bench_sections, rendered, stale


def test_committed_pages_match_the_committed_json():
    assert stale(ROOT) == [], "run `make figures` (python -m tools.figures) and commit"


def test_every_artefact_says_where_it_was_measured():
    arts = artefact.load_all(ROOT)
    assert "demo" in arts and any(n.startswith("bench-") for n in arts)
    for name, doc in arts.items():
        m = doc["measured"]
        assert m["host"]["cpu"] and m["host"]["cores"] >= 1, name
        assert len(m["host"]["load"]) == 3 and m["host"]["state"], name
        assert re.fullmatch(r"[0-9a-f]{40}", m["commit"]), name
        assert re.match(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00$", m["date"]), name
        assert "numpy" in m["packages"] and "scipy" in m["packages"], name
        assert doc["figures"], name


def test_the_readme_table_quotes_measured_values_only():
    block = pages.readme_block((ROOT / README).read_text())
    assert "not measured" not in block
    arts = artefact.load_all(ROOT)
    for key, art, _label in pages.README_ROWS:
        assert pages.fmt(pages.lookup(arts[art]["figures"], key)) in block, key
    # provenance lives in docs/figures.md only
    for doc in arts.values():
        assert doc["measured"]["commit"][:7] not in block
        assert doc["measured"]["date"][:10] not in block
    assert "docs/figures.md" in block


def test_the_pages_carry_no_commit_date_or_host_note():
    """Commit, date and free-text host notes are provenance kept in the JSON; the pages a
    user reads hold where it was measured (CPU, cores, quiet/busy, load), not a diary."""
    arts = artefact.load_all(ROOT)
    text = rendered(ROOT)[FIGURES_MD]
    for name, doc in arts.items():
        m = doc["measured"]
        assert m["commit"][:7] not in text, name
        assert m["date"][:16] not in text, name
        note = m["host"]["state"].partition(";")[2].strip()
        assert not note or note not in text, name
        assert f"{m['host']['cores']} cores, {m['host']['state'].split(':')[0]}" in text, name


def _copy_repo(tmp_path):
    for rel in (README, FIGURES_MD, "bench/__init__.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / rel, tmp_path / rel)
    shutil.copytree(ROOT / FIGURES_DIR, tmp_path / FIGURES_DIR)
    return tmp_path


def test_a_changed_figure_makes_both_pages_stale(tmp_path):
    root = _copy_repo(tmp_path)
    assert stale(root) == []
    path = root / FIGURES_DIR / "bench-diagnose.json"
    doc = json.loads(path.read_text())
    doc["figures"]["diagnose_60s_s"] = doc["figures"]["diagnose_60s_s"] * 1.5 + 1
    path.write_text(json.dumps(doc))
    assert sorted(map(str, stale(root))) == sorted([str(FIGURES_MD), str(README)])
    cmd = [sys.executable, "-m", "tools.figures", "--root", str(root)]
    assert subprocess.run(cmd + ["--check"], cwd=ROOT, capture_output=True,
                          timeout=120).returncode == 1
    assert subprocess.run(cmd, cwd=ROOT, capture_output=True, timeout=120).returncode == 0
    assert stale(root) == []
    assert pages.fmt(doc["figures"]["diagnose_60s_s"]) in (root / FIGURES_MD).read_text()


def test_a_section_without_artefact_is_listed_as_not_measured(tmp_path):
    root = _copy_repo(tmp_path)
    (root / FIGURES_DIR / "bench-design.json").unlink()
    text = rendered(root)[FIGURES_MD]
    assert "`python -m bench --save design`" in text
    assert "| structured H∞ design of the order-4 K∞ (s) | not measured |" in \
        rendered(root)[README]


def test_save_writes_the_figures_with_their_provenance(tmp_path, monkeypatch):
    root = _copy_repo(tmp_path)
    monkeypatch.setenv("RIGD_HOST_NOTE", "shared machine")
    p = artefact.save_bench_section(root, "identify", {"identify_bearing_s": 0.123,
                                                       "identify_bearing_fit_percent": 97.5},
                                    seconds=4.2)
    doc = json.loads(p.read_text())
    assert doc["command"] == "python -m bench identify" and doc["measured"]["seconds"] == 4.2
    assert doc["measured"]["host"]["state"].endswith("; shared machine")
    summary = tmp_path / "summary.json"
    demo = json.loads((ROOT / FIGURES_DIR / "demo.json").read_text())["figures"]
    summary.write_text(json.dumps({**demo, "run_time_s": 77.7, "big_unlisted_key": [1] * 9}))
    doc = json.loads(artefact.save_demo(root, summary).read_text())
    assert doc["figures"]["run_time_s"] == 77.7 and "big_unlisted_key" not in doc["figures"]
    text = rendered(root)
    assert "| `identify_bearing_s` | 0.123 |" in text[FIGURES_MD]
    assert "| `make demo`, the whole story (s) | 77.7 | `make demo` |" in text[README]


def test_demo_tables_render_the_diagnosis():
    from tools.figures.demo_tables import render

    s = {"damping_ratio_open": {f"P{p}bar_W0rpm_{a}": 0.05 for p in (4, 7) for a in "xy"},
         "damping_ratio_closed": {f"P{p}bar_W0rpm_{a}": 0.2 for p in (4, 7) for a in "xy"},
         "damping_increase": {f"P{p}bar_W0rpm_{a}": 4.0 for p in (4, 7) for a in "xy"},
         "design_method": "structured", "controller_order": 4, "gamma": 2.0,
         "robustness": {"n_realizations": 30, "all_stable": True},
         "diagnosis": {"named": ["actuator_dynamics"],
                       "named_by_submodel": {"actuator": [], "bearing": ["actuator_dynamics"]},
                       "fit_before": {"actuator": 97.5, "bearing": 68.2},
                       "fit_after": {"actuator": 97.5, "bearing": 93.1}}}
    text = render(s)
    assert "| bearing | `actuator_dynamics` | 68.20 % | 93.10 % | 31.80 → 6.90 |" in text
    assert "| actuator | nothing |" in text
    assert "| increase (x / y) | 4.00× / 4.00× | 4.00× / 4.00× | 3 / 6 |" in text


@pytest.mark.parametrize("v, shown", [(2_200_000.0, "2 200 000"), (0.69, "0.69"),
                                      (5.8e-4, "5.80e-04"), (True, "yes"), (12, "12"),
                                      ("cubic_stiffness", "`cubic_stiffness`")])
def test_values_are_shown_as_measured(v, shown):
    assert pages.fmt(v) == shown


def test_the_page_lists_every_bench_section():
    text = (ROOT / FIGURES_MD).read_text()
    for s in bench_sections(ROOT):
        assert f"### {s}\n" in text or f"`python -m bench --save {s}`" in text, s
