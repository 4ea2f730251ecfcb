"""Every ```sh block of README.md runs, as written, in a clean copy of what a clone holds
(config/ and examples/, nothing beside it: no data outside the repository, a fresh HOME, no
RIGD_* variables), and prints the figures the README quotes for it.

Conventions of the README's command blocks (cram-style):

* a command's comment after ``# →`` says what it prints; every number in it must be among the
  numbers the command prints, within 0.2 % of the printed value (or half a unit of the quoted
  figure's last digit, whichever is larger), and every name with an underscore in it (an
  effect's name, ``cubic_stiffness``) must be printed too;
* every command must exit with status 0;
* a command ending in ``&`` runs in the background until the block ends, then gets SIGTERM:
  ``rigd run`` must stop cleanly (exit 0, its documented stop), others must end (0, or 143:
  ended by that signal); the next command starts once it serves — ``rigd run`` when its
  ``--socket`` answers ``rigd ctl ping``, ``rigd web`` when it printed its address;
* ``make demo`` is represented by the output of one ``rigd demo --quick`` (made once per test
  run, tests/sharedruns.py), copied to ``demo-out/`` for the blocks that use it; ``make
  test`` is not run (it is the suite this test belongs to); ``--listen 127.0.0.1:8080`` is
  run on a free port (``:0``) so that a console already serving 8080 does not fail it.

Each block runs once (one test per block; the Silverbox and design blocks take about a
minute of CPU each).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from testpaths import ROOT

README = ROOT / "README.md"
BLOCK = re.compile(r"^```sh\n(.*?)^```", re.M | re.S)
NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:[.,]\d+)*(?:e[-+]?\d+)?")
CLAIM = "# →"
REL_TOL = 0.002
#: what the test runs instead of a command (module docstring): the quick demo's output is
#: copied to demo-out/ beforehand, so `make demo` is checked by the files it promises
REPRESENTED = {"make demo": "test -s demo-out/index.html && test -s demo-out/summary.json",
               "make test": "true"}

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]


@dataclass
class Command:
    line: str                 # the command as run
    claim: str                # what the README says it prints ("" if nothing)
    background: bool


def _parse(line: str) -> Command:
    cmd, claim = line, ""
    m = re.search(r"\s+#", line)
    if m:
        cmd, comment = line[:m.start()], line[m.start():].strip()
        claim = comment[len(CLAIM):].strip() if comment.startswith(CLAIM) else ""
    cmd = cmd.strip()
    background = cmd.endswith("&") and not cmd.endswith("&&")
    if background:
        cmd = cmd[:-1].strip()
    cmd = cmd.replace("--listen 127.0.0.1:8080", "--listen 127.0.0.1:0")
    return Command(cmd, claim, background)


def readme_blocks(text: str) -> list[list[Command]]:
    """The README's ```sh blocks as lists of commands (empty and comment lines dropped)."""
    out = []
    for body in BLOCK.findall(text):
        cmds = [_parse(ln) for ln in body.splitlines() if ln.strip()
                and not ln.lstrip().startswith("#")]
        out.append(cmds)
    return out


def numbers(text: str) -> list[float]:
    return [float(v.replace(",", "")) for v in NUMBER.findall(text)]


def _half_unit(token: str) -> float:
    t = token.replace(",", "")
    return 0.5 * 10 ** -len(t.split(".")[1]) if "." in t and "e" not in t else 0.5


def claim_problems(claim: str, printed: str) -> list[str]:
    """What of ``claim`` the command's output does not show (module docstring's rule)."""
    have = numbers(printed)
    bad = []
    for token in NUMBER.findall(claim):
        q = float(token.replace(",", ""))
        if not any(abs(q - p) <= max(REL_TOL * abs(p), _half_unit(token)) for p in have):
            bad.append(f"quoted {token} not printed (within 0.2 %)")
    for name in re.findall(r"\b[a-z]+(?:_[a-z0-9]+)+\b", claim):
        if name not in printed:
            bad.append(f"{name!r} not printed")
    return bad


def _script(cmds: list[Command]) -> str:
    lines = ["set -u"]
    for i, c in enumerate(cmds):
        if c.line in REPRESENTED:
            lines.append(f"echo '@@begin {i}'; {REPRESENTED[c.line]}; echo \"@@rc {i} $?\"")
            continue
        if c.background:
            lines.append(f"( exec {c.line} ) > bg{i}.out 2>&1 & echo $! > bg{i}.pid")
            words = shlex.split(c.line)
            if "--socket" in words and words[:2] == ["rigd", "run"]:
                sock = shlex.quote(words[words.index("--socket") + 1])
                ready = f"[ -S {sock} ] && rigd ctl --socket {sock} ping >/dev/null 2>&1"
            else:
                ready = f"grep -q 'http' bg{i}.out"
            # bounded wait for the process to serve (a file appearing, not a guess of time)
            lines.append(f"for k in $(seq 1200); do {ready} && break; "
                         f"kill -0 $(cat bg{i}.pid) 2>/dev/null || break; sleep 0.5; done")
            lines.append(f"echo '@@begin {i}'; {ready} && echo ready; echo \"@@rc {i} $?\"")
            continue
        lines.append(f"echo '@@begin {i}'; {c.line} 2>&1; echo \"@@rc {i} $?\"")
    lines.append("for f in bg*.pid; do [ -e \"$f\" ] || continue; p=$(cat \"$f\"); "
                 "kill -0 $p 2>/dev/null && echo \"@@alive $f\"; kill -TERM $p 2>/dev/null; "
                 "wait $p; echo \"@@exit $f $?\"; done")
    return "\n".join(lines) + "\n"


def _clean_env(home: Path) -> dict[str, str]:
    bindir = Path(sys.executable).parent
    if not (bindir / "rigd").exists():
        found = shutil.which("rigd")
        assert found, "the rigd command is not installed beside this Python"
        bindir = Path(found).parent
    env = {"PATH": f"{bindir}:/usr/local/bin:/usr/bin:/bin", "HOME": str(home),
           "LANG": "C.UTF-8", "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           # the compiled kernels of this checkout (keyed by their source): a clone's first
           # run compiles them once into the same place
           "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR",
                                             str(ROOT / ".venv" / "numba-cache"))}
    return env


BLOCKS = readme_blocks(README.read_text())


def test_the_readme_has_the_tour_blocks():
    firsts = [b[0].line.split()[:2] for b in BLOCKS]
    assert ["make", "demo"] in firsts
    joined = "\n".join(c.line for b in BLOCKS for c in b)
    for sub in ("rigd run", "rigd experiment", "rigd ctl", "rigd identify", "rigd compare",
                "rigd diagnose", "rigd design", "rigd web", "examples/data/silverbox.csv.gz"):
        assert sub in joined, sub
    assert "../shared" not in README.read_text()


@pytest.mark.parametrize("k", range(len(BLOCKS)),
                         ids=[f"block{k}-{'_'.join(b[0].line.split()[:2])}"
                              for k, b in enumerate(BLOCKS)])
def test_readme_block_runs_and_prints_what_it_says(k, tmp_path, request):
    work = tmp_path / "clone"
    work.mkdir()
    for d in ("config", "examples"):
        shutil.copytree(ROOT / d, work / d)
    cmds = BLOCKS[k]
    if any("demo-out" in c.line or c.line == "make demo" for c in cmds):
        # the quick demo's output, made once per test run (tests/conftest.py quick_demo)
        shutil.copytree(request.getfixturevalue("quick_demo"), work / "demo-out")
    assert not any((p / "shared" / "data").exists() for p in work.parents)
    (tmp_path / "home").mkdir()
    proc = subprocess.run(["bash", "-c", _script(cmds)], cwd=work, env=_clean_env(
        tmp_path / "home"), capture_output=True, text=True, timeout=1700)
    out = proc.stdout
    parts = dict(re.findall(r"^@@begin (\d+)\n(.*?)(?=^@@rc \1 )", out, re.M | re.S))
    rcs = dict(re.findall(r"^@@rc (\d+) (\d+)$", out, re.M))
    problems = []
    for i, c in enumerate(cmds):
        if str(i) not in rcs:
            problems.append(f"{c.line}: did not run")
            continue
        text = parts.get(str(i), "")
        if c.background:
            text = (work / f"bg{i}.out").read_text()
            if rcs[str(i)] != "0":
                problems.append(f"{c.line}: never served (output: {text[-500:]!r})")
            continue
        if rcs[str(i)] != "0":
            problems.append(f"{c.line}: exit status {rcs[str(i)]}: {text[-800:]}")
            continue
        problems += [f"{c.line}: {p}" for p in claim_problems(c.claim, text)]
    daemons = {f"bg{i}.pid": c.line.startswith("rigd run") for i, c in enumerate(cmds)}
    for pid in re.findall(r"^@@exit (\S+) (\d+)$", out, re.M):
        if f"@@alive {pid[0]}" not in out:
            problems.append(f"background {pid[0]} had ended before the block did")
        elif pid[1] != "0" and not (pid[1] == "143" and not daemons.get(pid[0])):
            problems.append(f"background {pid[0]}: exit status {pid[1]} after SIGTERM")
    assert not problems, "\n".join(problems) + "\n--- output ---\n" + out[-3000:] + \
        "\n--- stderr ---\n" + proc.stderr[-2000:]


@pytest.mark.parametrize("claim, printed, ok", [
    ("V2 86.89 %", "[generic] OE fit: V2 86.89 %", True),
    ("V2 86.89 %", "[generic] OE fit: V2 86.50 %", False),      # 0.45 % off
    ("V2 86.89 %", "[generic] OE fit: V2 86.93 %", True),       # within 0.2 %
    ("names cubic_stiffness", "cubic_stiffness score 0.98", True),
    ("names cubic_stiffness", "delay score 0.98", False),
    ("50000 cycles", "lock-step: 50,000 cycles in 0.1 s", True),
])
def test_the_claim_rule(claim, printed, ok):
    assert (claim_problems(claim, printed) == []) is ok
