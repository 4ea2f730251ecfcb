"""The real daemon whose loop thread dies: the front-end is told to hold its safe voltage at
once (not only after its host timeout), the fault is latched and reported (systemd STATUS=,
the log), and ``rigd run`` exits non-zero so systemd's Restart=on-failure restarts it.

The daemon is the real ``rigd run`` process with the real serial driver on a pty, fed by the
front-end emulator; the only thing added is a start-up wrapper that makes the cycle raise once
the process gets SIGRTMIN+1 (a stand-in for any bug in the loop thread; SIGUSR1 is the
daemon's SAFE signal, SIGUSR2 its stack dump, which would replace the wrapper's handler).
"""

import json
import signal
import socket
import sys
import time

import daemon_helpers
import numpy as np
import pytest
from daemon_helpers import Daemon, make_config

WRAPPER = """\
import signal, sys
import rigd.loop.cycle as C

armed = []
real = C.rt_cycle

def rt_cycle(*args):
    if armed:
        raise RuntimeError("injected: the cycle raised")
    real(*args)

if __name__ == "__main__":      # the socket process is spawned: it must not run the daemon
    C.rt_cycle = rt_cycle
    signal.signal(signal.SIGRTMIN + 1, lambda *a: armed.append(1))
    from rigd.cli import main
    sys.exit(main())
"""


@pytest.fixture()
def emulator(tmp_path):
    # The front-end emulator runs in a process of its own (emuproc.py), as the real front-end
    # is a device of its own. As a thread of this test process it ran at normal priority and
    # shared this process's interpreter lock: on a loaded machine it was starved for longer
    # than the driver's frame timeout, and the daemon latched driver_status (code 9) before
    # the injected loop death (issue 16 item 6).
    from emuproc import EmulatorProcess

    emu = EmulatorProcess(str(tmp_path / "frontend"), fs=5000.0, hold_timeout=0.5,
                          tx_buffer_s=0.5)
    yield emu
    emu.stop()


def test_loop_death_in_the_daemon(tmp_path, monkeypatch, emulator):
    wrapper = tmp_path / "rigd-wrapped"
    wrapper.write_text(f"#!{sys.executable}\n{WRAPPER}")
    wrapper.chmod(0o755)
    monkeypatch.setattr(daemon_helpers, "RIGD", str(wrapper))
    cfg = make_config(tmp_path, clock={"spin_us": 0.0},
                      drivers={"fast": {"name": "serial", "options": {
                          "port": emulator.port, "timeout_ms": 250.0, "fault_on_gap": False}}},
                      supervisor={"stale_frames": 0})
    d = Daemon(tmp_path, cfg)
    try:
        d.wait_notify("READY=1")
        assert _wait(lambda: emulator.drive_frames > 100 and not emulator.holding)
        assert int(emulator.last_drive[1]) & 1 == 1            # outputs enabled by the host
        client = _Client(d.sock)                               # connected before the death
        st0 = client.status()
        assert st0["fault"]["code"] == 0, st0["fault"]
        d.proc.send_signal(signal.SIGRTMIN + 1)
        # what `rigd ctl status` shows while the daemon lingers before exiting
        st = _poll(lambda: client.status(), lambda st: st["fault"]["name"] == "loop_died")
        assert st["running"] is False and "injected" in st["loop_error"], st
        client.close()
        code = d.proc.wait(daemon_helpers.PROCESS_S)   # the hang bound of every process wait
    finally:
        code, _ = d.stop()
    log = d.log()
    assert code == 3, log
    assert "rigd run: the loop died (RuntimeError('injected: the cycle raised'))" in log
    # the host told the front-end to hold (enable bit cleared in its last drive frame): the
    # device's host-timeout hold (0.5 s here) was not needed
    assert int(emulator.last_drive[1]) & 1 == 0
    assert emulator.holding and np.all(emulator.applied == emulator.hold_v)
    assert any("STATUS=FAULT loop_died" in m for m in d.messages), d.messages
    assert any("STOPPING=1" in m for m in d.messages)


def _wait(pred, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return pred()


class _Client:
    """A raw control-socket client (one JSON line each way), kept open across the death."""

    def __init__(self, path):
        self.s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.s.settimeout(10.0)
        self.s.connect(path)
        self.f = self.s.makefile("r")
        self.n = 0

    def status(self):
        self.n += 1
        self.s.sendall(json.dumps({"id": self.n, "cmd": "status"}).encode() + b"\n")
        reply = json.loads(self.f.readline())
        assert reply["ok"], reply
        return reply["result"]

    def close(self):
        self.f.close()
        self.s.close()


def _poll(get, pred, timeout=30.0):
    end = time.monotonic() + timeout
    v = get()
    while not pred(v) and time.monotonic() < end:
        time.sleep(0.02)
        v = get()
    assert pred(v), v
    return v
