"""`rigd ctl` against a real server (in-process, loop double) through the CLI entry point."""

import json
import os
import select
import socket
import subprocess
import sys
import time

import pytest
from fakeloop import FakeLoop

from rigd.cli import main
from rigd.controller import save_controller
from rigd.errors import InputError
from rigd.service.client import ControlClient
from rigd.service.protocol import Dispatcher
from rigd.service.server import RESERVED, ControlServer


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
    save_controller(tmp_path / "k.yaml", [[0.5]], [[0.0, 0.0]], [[0.0], [0.0]],
                    [[0.0, 0.0], [0.0, 0.0]], fs_hz=5000.0)
    assert main(["ctl", "--socket", path, "load", "k.yaml"]) == 0
    assert ("load_controller", str(tmp_path / "k.yaml")) in loop.calls


def test_ctl_errors_are_one_line(sock, capsys, tmp_path):
    path, _ = sock
    # read by `rigd ctl` itself (never by the daemon): refused naming the file, not quoting it
    assert main(["ctl", "--socket", path, "load", "/etc/passwd"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigd ctl: /etc/passwd: ") and "root:" not in err, err
    assert len(err.splitlines()) == 1
    assert main(["ctl", "--socket", str(tmp_path / "none.sock"), "status"]) == 2
    assert "no daemon socket" in capsys.readouterr().err
    exp = tmp_path / "x.yaml"
    exp.write_text("kind: prbs\n")
    assert main(["ctl", "--socket", path, "start", str(exp)]) == 2
    assert "not available" in capsys.readouterr().err


def _wait_hangup(s: socket.socket, timeout: float = 60.0) -> None:
    """Wait until the server has closed its end of ``s`` (POLLHUP), its refusal line sent."""
    p = select.poll()
    p.register(s, select.POLLHUP)
    end = time.monotonic() + timeout
    while not any(ev & select.POLLHUP for _, ev in p.poll(100)):
        assert time.monotonic() < end, "the server never closed the refused connection"


def test_ctl_refused_at_the_door_says_so_never_exit_0(tmp_path, capsys, monkeypatch):
    """A client the full daemon refuses at the door (one error line, then close) and that sends
    its request only after the close (a busy machine: `rigd ctl` is slower than the daemon)
    gets EPIPE on its send: `rigd ctl` says "too many clients" in one line, exit 2 — it was
    exit 0 with no output (the CLI took the socket's broken pipe for a closed stdout)."""
    with ControlServer(tmp_path / "s.sock", Dispatcher(FakeLoop()).handle_line,
                       max_clients=1, evict_idle_s=None) as srv:
        held = []
        for _ in range(1 + RESERVED):        # the one slot and the ones kept for control
            held.append(socket.socket(socket.AF_UNIX, socket.SOCK_STREAM))
            held[-1].connect(srv.path)
        end = time.monotonic() + 60
        while srv.stats["connections"] < len(held):
            assert time.monotonic() < end
            time.sleep(0.01)
        connect = ControlClient.connect

        def connect_then_wait(self):
            connect(self)
            _wait_hangup(self._sock)      # the refusal is in, the server's end closed
            return self

        monkeypatch.setattr(ControlClient, "connect", connect_then_wait)
        try:
            assert main(["ctl", "--socket", srv.path, "status"]) == 2
            out = capsys.readouterr()
            assert out.out == ""
            assert out.err.strip() == (f"rigd ctl: {srv.path}: the daemon closed the connection "
                                       "before the request: too many clients (max 1)")
            # the library raises the same one line (rigd web, benches)
            with pytest.raises(InputError, match=r"before the request: too many clients"):
                ControlClient(srv.path).request("ping")
        finally:
            for s in held:
                s.close()


def test_a_broken_pipe_other_than_stdout_is_exit_2(monkeypatch, capsys):
    """Only a closed stdout (`rigd ctl status | head`) ends quietly with 0; a broken pipe of
    anything else is one line and exit 2."""
    import rigd.cli.ctl as ctl

    def broken(args):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(ctl, "run", broken)
    assert main(["ctl", "--socket", "/nonexistent", "status"]) == 2
    assert "broken pipe" in capsys.readouterr().err


def test_closed_stdout_is_quiet_exit_0(tmp_path):
    """`rigd ctl ... | head`: the reader closes the pipe; the CLI ends with 0 and no traceback."""
    code = ("import sys, rigd.cli.ctl as ctl\n"
            "from rigd.cli import main\n"
            "def run(args):\n"
            "    for _ in range(100000):\n"
            "        print('x' * 79)\n"
            "    return 0\n"
            "ctl.run = run\n"
            "sys.exit(main(['ctl', '--socket', '/nonexistent', 'status']))\n")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.read(100)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(600) == 0, err
    assert err == ""
