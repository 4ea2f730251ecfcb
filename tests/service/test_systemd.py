"""The unit file, checked by systemd-analyze verify.

``verify`` also checks that ExecStart's binary exists. The shipped unit points at the install
location (/opt/rigd/.venv/bin/rigd), absent on a build machine, so the test verifies a copy
whose ExecStart points at this checkout's ``rigd`` (every other line unchanged) and asserts
that the shipped file fails *only* for that reason. Any warning (unknown key, bad value,
wrong section) fails the test.
"""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "systemd" / "rigd.service"
SA = shutil.which("systemd-analyze")

pytestmark = pytest.mark.skipif(SA is None, reason="systemd-analyze not installed")


def _verify(path):
    return subprocess.run([SA, "verify", str(path)], capture_output=True, text=True, timeout=60)


def test_unit_verifies_with_existing_binary(tmp_path):
    rigd_bin = Path(sys.executable).parent / "rigd"
    assert rigd_bin.exists()
    text = UNIT.read_text()
    assert "ExecStart=/opt/rigd/.venv/bin/rigd " in text
    copy = tmp_path / "rigd.service"
    copy.write_text(text.replace("ExecStart=/opt/rigd/.venv/bin/rigd ", f"ExecStart={rigd_bin} "))
    r = _verify(copy)
    assert r.returncode == 0 and r.stderr.strip() == "", r.stderr


def test_shipped_unit_only_misses_the_installed_binary():
    r = _verify(UNIT)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    if Path("/opt/rigd/.venv/bin/rigd").exists():
        assert r.returncode == 0 and not lines
    else:
        assert lines and all("/opt/rigd/.venv/bin/rigd" in ln for ln in lines), lines


def test_unit_contract():
    text = UNIT.read_text()
    keys = dict(re.findall(r"^(\w+)=(.*)$", text, re.M))
    assert keys["Type"] == "notify" and keys["WatchdogSec"]
    assert keys["LimitRTPRIO"] and keys["LimitMEMLOCK"] == "infinity"
    assert keys["ProtectSystem"] == "strict" and keys["NoNewPrivileges"] == "yes"
    assert keys["PrivateTmp"] == "yes" and keys["User"] == "rigd"
    assert not re.search(r"^RestrictRealtime=", text, re.M)  # would forbid SCHED_FIFO
    assert "--socket /run/rigd/rigd.sock" in keys["ExecStart"]
    dropin = (ROOT / "systemd" / "rigd-affinity.conf").read_text()
    assert re.search(r"^CPUAffinity=\d", dropin, re.M)
