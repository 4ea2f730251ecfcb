"""Fault injection on real daemon processes: the loop stands still (docs/service.md, "What
happens when…"; the front-end and the PLC killed and brought back: test_faults_inputs.py).

Each daemon test runs the real ``rigd run`` process (real-time clock, control socket,
NOTIFY_SOCKET, ``--record``), injects the fault from outside — SIGSTOP of the daemon — and
asserts what a rig engineer relies on: the fault list names what happened, ``status`` and
``ping`` say it while it lasts, the recording keeps at least every frame it had flushed before
the fault, and with the serial front-end the valves are safe in hardware (its host heartbeat,
also tested on its own on a pseudo-terminal pair). ``status`` reads its own writes after a
SAFE under a siege of browser streams and idle clients.
"""

import json
import os
import signal
import subprocess
import time

import numpy as np
import pytest
from daemon_helpers import PROCESS_S, RIGD, Daemon, make_config
from faultkit import read_frames

from rigd.frame import REC
from rigd.recording.h5sink import open_recording

#: the stall bound of these daemons, s: far below the 1.5 s stall injected, far above what a
#: loaded test machine does to a SCHED_FIFO loop (the derived default is tested in tests/loop)
STALL_S = 0.3
#: how long the daemon is stopped, s (the issue's must-show)
STOP_S = 1.5


def _config(tmp_path, **sections):
    sup = {"stall_s": STALL_S, **sections.pop("supervisor", {})}
    return make_config(tmp_path, clock={"spin_us": 0.0}, supervisor=sup, **sections)


def _until(pred, what, timeout=PROCESS_S, every=0.02):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = pred()
        if v:
            return v
        time.sleep(every)
    raise AssertionError(f"timed out waiting for {what}")


def _flushed(path):
    """Frames readable in the recording now (what survives any end from here on)."""
    try:
        with open_recording(path) as f:
            return int(f["frames"].shape[0])
    except (OSError, KeyError):
        return 0


def _ctl(d, *args):
    return subprocess.run([RIGD, "ctl", "--socket", d.sock, *args], capture_output=True,
                          text=True, timeout=PROCESS_S)


def _status(d):
    r = _ctl(d, "status", "--json")
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def _assert_contiguous(fr, at_least):
    seq = fr[:, REC["seq"]]
    assert len(fr) >= at_least, f"{len(fr)} frames on disk, {at_least} were flushed before"
    assert np.all(np.diff(seq) == 1), "recorded frames are contiguous"


def test_sigstop_of_the_daemon_latches_loop_stall(tmp_path):
    rec = tmp_path / "main.h5"
    d = Daemon(tmp_path, _config(tmp_path), "--record", str(rec))
    stopped = False
    try:
        d.wait_notify("READY=1")
        st = _status(d)
        assert st["stalled"] is False and st["stall_bound_s"] == pytest.approx(STALL_S)
        assert st["age_s"] is not None and st["age_s"] < STALL_S, st
        assert st["fault"]["code"] == 0, st["fault"]
        assert _ctl(d, "ping").returncode == 0
        n0 = _until(lambda: _flushed(rec), "a first flush of the recording")
        wd0 = sum("WATCHDOG=1" in m for m in d.messages)
        t_stop = time.monotonic()
        os.kill(d.proc.pid, signal.SIGSTOP)
        stopped = True
        # during the stall: the socket process answers from the SAFE word
        st = _until(lambda: (lambda s: s if s["stalled"] else None)(_status(d)),
                    "status to say stalled", timeout=STOP_S + PROCESS_S)
        assert st["age_s"] > STALL_S, st
        assert st["fault"]["name"] == "loop_stall", st["fault"]
        assert "stood still" in st["fault"]["text"]
        assert "STALLED" in _ctl(d, "status").stdout
        ping = _ctl(d, "ping")
        assert ping.returncode != 0 and "not cycling" in ping.stderr, (ping.stdout, ping.stderr)
        wd_during = sum("WATCHDOG=1" in m for m in d.messages)
        left = STOP_S - (time.monotonic() - t_stop)
        if left > 0:
            time.sleep(left)             # the injected fault: the process stays stopped
        assert sum("WATCHDOG=1" in m for m in d.messages) == wd_during, \
            "no WATCHDOG=1 while the loop stands"
        os.kill(d.proc.pid, signal.SIGCONT)
        stopped = False
        st = _until(lambda: (lambda s: s if not s["stalled"] and s["seq"] > st["seq"]
                             else None)(_status(d)), "the loop to cycle again")
        assert st["fault"]["name"] == "loop_stall", st["fault"]
        faults = json.loads(_ctl(d, "faults", "--json").stdout)["faults"]
        assert [f["name"] for f in faults] == ["loop_stall"], faults
        length = st["stall"]["length_s"]
        assert length >= STOP_S * 0.9, st["stall"]
        assert _until(lambda: sum("WATCHDOG=1" in m for m in d.messages) > wd_during,
                      "WATCHDOG=1 again once the loop cycles")
        assert wd_during >= wd0
        assert _ctl(d, "ping").returncode == 0
    finally:
        if stopped:
            os.kill(d.proc.pid, signal.SIGCONT)
        code, _ = d.stop(signal.SIGTERM)
    assert code in (0, 1), d.log()
    fr = read_frames(rec)
    _assert_contiguous(fr, n0)
    fault = fr[:, REC["fault"]]
    hit = np.flatnonzero(fault != 0)
    assert hit.size and fault[hit[0]] == 15, "loop_stall recorded in the fault channel"


@pytest.fixture()
def emulator(tmp_path):
    from emuproc import EmulatorProcess

    emus = []

    def make():
        emu = EmulatorProcess(str(tmp_path / "frontend"), fs=5000.0, hold_timeout=0.5,
                              tx_buffer_s=0.5)
        emus.append(emu)
        return emu

    yield make
    for e in emus:
        try:
            e.stop()
        except Exception:  # noqa: BLE001 - a killed emulator
            pass


def _serial_config(tmp_path, port):
    return _config(tmp_path, drivers={"fast": {"name": "serial", "options": {
        "port": port, "timeout_ms": 250.0, "fault_on_gap": False, "reconnect_s": 0.1}}},
        supervisor={"stale_frames": 0})


def test_frozen_host_is_safe_in_the_front_end(tmp_path, emulator):
    """SIGSTOP of the daemon driving the serial front-end: the front-end's host heartbeat
    holds its safe voltage once no drive frame came for its host timeout; the daemon latches
    loop_stall; the front-end is driven again once the loop runs."""
    emu = emulator()
    rec = tmp_path / "main.h5"
    d = Daemon(tmp_path, _serial_config(tmp_path, emu.port), "--record", str(rec))
    stopped = False
    try:
        d.wait_notify("READY=1")
        _until(lambda: emu.drive_frames > 100 and not emu.holding, "the host to drive")
        n0 = _until(lambda: _flushed(rec), "a first flush of the recording")
        os.kill(d.proc.pid, signal.SIGSTOP)
        stopped = True
        _until(lambda: emu.holding, "the front-end to hold its safe voltage")
        np.testing.assert_allclose(emu.applied, emu.hold_v)
        _until(lambda: _status(d)["stalled"], "status to say stalled")
        os.kill(d.proc.pid, signal.SIGCONT)
        stopped = False
        st = _until(lambda: (lambda s: s if not s["stalled"] else None)(_status(d)),
                    "the loop to cycle again")
        assert st["fault"]["name"] == "loop_stall", st["fault"]
        n_frames = emu.drive_frames
        _until(lambda: emu.drive_frames > n_frames + 100, "drive frames again")
    finally:
        if stopped:
            os.kill(d.proc.pid, signal.SIGCONT)
        code, _ = d.stop(signal.SIGTERM)
    assert code in (0, 1), d.log()
    _assert_contiguous(read_frames(rec), n0)


def test_front_end_heartbeat_holds_on_a_replaying_host(tmp_path):
    """The front-end's host heartbeat on a pseudo-terminal pair: enabled drive frames whose
    host counter advances are applied; the same frame replayed (a frozen host whose link
    repeats it) is no heartbeat — the device holds its safe voltage within its host timeout
    while the frames keep arriving; an advancing frame drives it again; silence holds too."""
    import threading

    from emuproc import EmulatorProcess

    from rigd_drivers.serial import protocol as sp

    emu = EmulatorProcess(str(tmp_path / "frontend"), fs=5000.0, hold_timeout=0.2)
    fd = os.open(emu.port, os.O_RDWR | os.O_NOCTTY)
    buf = np.zeros(sp.DRIVE_FRAME, np.uint8)
    frame = {"seq": 1, "advance": True, "send": True}
    stop = threading.Event()

    def host():
        drive = np.array([6.0, 4.0, 6.5, 3.5])
        while not stop.wait(0.005):
            if frame["advance"]:
                frame["seq"] += 1
            if frame["send"]:
                sp.encode_drive(buf, frame["seq"], True, drive)
                os.write(fd, buf.tobytes())
            try:
                os.read(fd, 65536)       # drain the sensor frames
            except BlockingIOError:
                pass

    os.set_blocking(fd, False)
    t = threading.Thread(target=host, daemon=True)
    t.start()
    try:
        _until(lambda: not emu.holding, "the device to apply the host's drive")
        np.testing.assert_allclose(emu.applied, [6.0, 4.0, 6.5, 3.5], atol=1e-3)
        frame["advance"] = False                       # the host froze, its link replays
        n = emu.repeated_frames
        _until(lambda: emu.holding, "the device to hold on a replaying host")
        np.testing.assert_allclose(emu.applied, emu.hold_v)
        assert emu.repeated_frames > n, "frames kept arriving while it held"
        frame["advance"] = True
        _until(lambda: not emu.holding, "the device to apply an advancing host again")
        frame["send"] = False                          # silence
        _until(lambda: emu.holding, "the device to hold on a silent host")
    finally:
        stop.set()
        t.join(5)
        os.close(fd)
        emu.stop()


@pytest.mark.timeout(3 * PROCESS_S)
def test_status_reads_its_own_writes_after_safe_under_siege(tmp_path):
    """Right after ``rigd ctl safe`` returns "latched at cycle N", ``rigd ctl status --json``
    shows that fault and a cycle >= N — with 100 browser streams on ``rigd web`` and 70 idle
    clients holding the daemon's socket (more than its 64 slots and the 4 kept for control:
    each `rigd ctl` gets a slot because the connection idle longest is closed for it, and
    says so), three times over (reset in between)."""
    import re
    import socket as so
    import sys

    from testpaths import ROOT

    if str(ROOT / "tests" / "web") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / "web"))
    from test_safe_under_siege import _head, _open_stream, _Siege
    from webproc import daemon_and_web

    streams, idle, siege = [], [], None
    with daemon_and_web(tmp_path, daemon_args=("--client-idle-s", str(20 * PROCESS_S))) \
            as (d, web):
        try:
            for _ in range(100):
                streams.append(_open_stream(web.url, web.token))
            assert all(_head(s).startswith(b"HTTP/1.1 200") for s in streams)
            end = time.monotonic() + PROCESS_S
            while len(idle) < 70 and time.monotonic() < end:
                c = so.socket(so.AF_UNIX, so.SOCK_STREAM)
                c.setblocking(False)      # a full listen backlog waits for the niced
                try:                      # socket process: never block the test on it
                    c.connect(d.sock)
                    idle.append(c)
                except BlockingIOError:
                    c.close()
                    time.sleep(0.01)
            assert len(idle) == 70
            siege = _Siege(streams)
            siege.start()
            for _ in range(3):
                r = _ctl(d, "safe")
                assert r.returncode == 0, r.stderr
                n = int(re.search(r"latched at cycle (\d+)", r.stdout).group(1))
                st = _status(d)              # at once: no wait for a snapshot
                assert st["fault"]["name"] == "operator_safe", (st["fault"], n)
                assert st["fault"]["seq"] == n and st["seq"] >= n, (st["seq"], st["fault"], n)
                assert st["controller"]["enabled"] is False
                assert _ctl(d, "reset").returncode == 0
                st = _status(d)
                assert st["fault"]["code"] == 0, st["fault"]
            said = []                          # what the idle connections were told
            for c in idle:
                try:
                    said.append(c.recv(4096, so.MSG_DONTWAIT))
                except (BlockingIOError, OSError):
                    said.append(b"")
            assert sum(b"idle longest" in x for x in said) >= 6, said   # one per `rigd ctl`
        finally:
            if siege is not None:
                siege.stop()
            for s in streams + idle:
                s.close()
