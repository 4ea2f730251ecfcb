"""docs/diagnose.md stays true: the walk-through on a non-rotor benchmark system (the 3-mass
chain) is executed as written — its record generator and every ``rigd`` command — and every
figure its comment lines quote must be among the numbers the command prints today."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from rigd.cli import main

DOC = Path(__file__).resolve().parents[2] / "docs" / "diagnose.md"
SECTION = "## Walk-through on a non-rotor benchmark system"
NUM = re.compile(r"-?\d+(?:\.\d+)?")


def walkthrough() -> tuple[str, dict[str, str], list[tuple[str, list[str]]]]:
    """(python generator code, shell variables, [(rigd command, quoted comment lines)])."""
    text = DOC.read_text()
    assert SECTION in text, f"{DOC} lost its section {SECTION!r}"
    block = text.split(SECTION, 1)[1].split("```", 2)[1]
    lines = block.strip("\n").splitlines()
    code, vars_, cmds = [], {}, []
    i = 0
    while i < len(lines):
        ln = lines[i]
        if ln.startswith('python -c "'):
            body = [ln[len('python -c "'):]]
            while not body[-1].rstrip().endswith('"'):
                i += 1
                body.append(lines[i])
            body[-1] = body[-1].rstrip()[:-1]
            code.append("\n".join(body))
        elif re.match(r"^[A-Z]+=", ln):
            k, v = ln.split("=", 1)
            vars_[k] = shlex.split(v)[0]
        elif ln.startswith("rigd "):
            cmd, _, inline = ln.partition("  #")
            cmds.append((cmd.strip(), [inline] if inline.strip() else []))
        elif ln.lstrip().startswith("#") and cmds:
            cmds[-1][1].append(ln.lstrip()[1:])
        i += 1
    return "\n".join(code), vars_, cmds


def test_walkthrough_is_parsed():
    code, vars_, cmds = walkthrough()
    assert "three_mode" in code and "C" in vars_
    assert len(cmds) >= 6 and all(quoted for _, quoted in cmds[:3])


@pytest.mark.slow
def test_non_rotor_walkthrough_numbers_are_what_the_commands_print(tmp_path, monkeypatch,
                                                                   capsys):
    code, vars_, cmds = walkthrough()
    monkeypatch.chdir(tmp_path)
    exec(compile(code, str(DOC), "exec"), {})  # noqa: S102 - the doc's own generator
    assert Path("chain.csv").exists()
    for cmd, quoted in cmds:
        argv = []
        for tok in shlex.split(cmd)[1:]:
            argv += shlex.split(vars_[tok[1:]]) if tok.startswith("$") else [tok]
        assert main(argv) == 0, cmd
        printed = set(NUM.findall(capsys.readouterr().out))
        for line in quoted:
            missing = [v for v in NUM.findall(line) if v not in printed]
            assert not missing, (f"docs/diagnose.md quotes {missing} for `{cmd}` but it "
                                 f"prints {sorted(printed)}: {line.strip()!r}")
