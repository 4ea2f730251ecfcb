"""`rigd ctl` against a real server (in-process, loop double) through the CLI entry point."""

import json
import os

import pytest
from fakeloop import FakeLoop

from rigd.cli import main
from rigd.service.protocol import Dispatcher
from rigd.service.server import ControlServer


@pytest.fixture()
def sock(tmp_path):
    loop = FakeLoop()
    with ControlServer(tmp_path / "s.sock", Dispatcher(loop, info=lambda: {
            "pid": os.getpid(), "version": "t"}).handle_line) as srv:
        yield srv.path, loop


def test_ctl_commands(sock, capsys, tmp_path, monkeypatch):
    path, loop = sock
    assert main(["ctl", "--socket", path, "ping"]) == 0
    assert "rigd alive" in capsys.readouterr().out
    assert main(["ctl", "--socket", path, "op", "2500", "5"]) == 0
    assert main(["ctl", "--socket", path, "status", "--json"]) == 0
    st = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert st["omega_rpm"] == 2500 and st["p_inj_bar"] == 5
    assert main(["ctl", "--socket", path, "timing"]) == 0
    out = capsys.readouterr().out
    assert "compute_us:" in out and "p99: 2" in out
    assert main(["ctl", "--socket", path, "enable"]) == 0 and loop.enabled
    assert main(["ctl", "--socket", path, "disable"]) == 0 and not loop.enabled
    monkeypatch.chdir(tmp_path)  # restored after the test: later tests use relative config/ paths
    assert main(["ctl", "--socket", path, "load", "k.yaml"]) == 0
    assert ("load_controller", str(tmp_path / "k.yaml")) in loop.calls


def test_ctl_errors_are_one_line(sock, capsys, tmp_path):
    path, _ = sock
    assert main(["ctl", "--socket", path, "load", "/etc/passwd"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigd ctl: daemon: ") and "not a controller" in err
    assert len(err.splitlines()) == 1
    assert main(["ctl", "--socket", str(tmp_path / "none.sock"), "status"]) == 2
    assert "no daemon socket" in capsys.readouterr().err
    assert main(["ctl", "--socket", path, "start", "/x.yaml"]) == 2
    assert "not available" in capsys.readouterr().err
