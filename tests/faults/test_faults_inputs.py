"""Fault injection on real daemons (``rigd run`` processes, their socket process and HDF5
writer): what a client may hand the daemon, and the inputs the rig hands it.

* ``rigd ctl load`` by another uid of a file that uid cannot read: refused, nothing of the
  file printed (the daemon opens no file a client names: the client reads it and sends it);
* extreme controllers (B = 1e300, NaN, an unstable closed loop without ``design_plant``)
  refused in one line by ``rigd ctl load`` and by the web upload alike;
* the serial front-end killed for 2 s and brought back: ``e_x`` of the outage is NaN in the
  HDF5 record (invalid, not the held value) and the fault list names the disconnect;
* the PLC (Modbus) killed and brought back: ``p_inj_bar`` of the outage is NaN and the loss
  is named with its reason.

Every test with a record asserts that the frames on disk are at least those flushed before
the fault, and the fault list.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from daemon_helpers import PROCESS_S, RIGD, ROOT, Daemon, make_config

from rigd.frame import REC
from rigd.recording.h5sink import open_recording

#: real daemons on a shared, loaded 2-core machine: a start can take minutes (hang bounds, not
#: timing: each wait is on an event)
pytestmark = pytest.mark.timeout(3 * PROCESS_S)

SECRET = "kGHx7Qe2-this-is-the-web-control-token-9f3a"


def _frames(path, last=None):
    """The frames on disk (the ``last`` ones only, when given), or None while unreadable."""
    try:
        with open_recording(path) as f:
            ds = f["frames"]
            ds.refresh()
            n = ds.shape[0]
            out = ds[max(0, n - last) if last else 0:n]
    except (OSError, KeyError):
        return None
    written = np.flatnonzero(np.any(out != 0, axis=1))   # rows allocated, not yet written
    return out[:written[-1] + 1] if written.size else out[:0]


def _n_frames(path) -> int:
    fr = _frames(path, last=4096)
    if fr is None or not len(fr):
        return 0
    return int(fr[-1, REC["seq"]] - _first_seq(path) + 1)


def _first_seq(path) -> float:
    with open_recording(path) as f:
        return float(f["frames"][0, REC["seq"]])


def _settled(path, n_min):
    """The last frames once at least ``n_min`` are on disk, fault-free and valid; else None."""
    if _n_frames(path) < n_min:
        return None
    fr = _frames(path, last=2000)
    ok = not np.any(fr[:, REC["fault"]]) and np.all(np.isfinite(fr[:, REC["e_x"]]))
    return fr if ok else None


def _wait(pred, timeout=PROCESS_S, what="condition", every=0.05):
    end = time.monotonic() + timeout
    while True:
        v = pred()
        if v is not None and v is not False:
            return v
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(every)


def _open_dir() -> Path:
    """A folder another uid can traverse (pytest's tmp_path is 0700)."""
    d = Path(tempfile.mkdtemp(prefix="rigd-faults-", dir="/tmp"))
    d.chmod(0o755)
    return d


#: run as root, then act as ``nobody``: what the interpreter needs is imported first (the
#: interpreter's own files may lie where nobody cannot read them, e.g. under /root)
AS_NOBODY = """
import base64, binascii, json, os, pwd, socket, sys
import control, numpy, pydantic, yaml
import rigd.cli, rigd.cli.ctl, rigd.service.client, rigd.controller, rigd.configio
pw = pwd.getpwnam("nobody")
os.setgroups([])
os.setgid(pw.pw_gid)
os.setuid(pw.pw_uid)
assert os.geteuid() == pw.pw_uid
if sys.argv[1] == "raw":          # the socket spoken to directly: a path alone
    s = socket.socket(socket.AF_UNIX)
    s.connect(sys.argv[2])
    s.sendall((json.dumps({"id": 1, "cmd": "controller.load", "path": sys.argv[3]})
               + "\\n").encode())
    print(s.makefile().readline().strip())
    sys.exit(0)
sys.exit(rigd.cli.main(sys.argv[1:]))
"""


def _as_nobody(*args, cwd):
    return subprocess.run([sys.executable, "-c", AS_NOBODY, *args], capture_output=True,
                          text=True, timeout=PROCESS_S, cwd=str(cwd))


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to act as another uid (CI is root)")
def test_ctl_load_as_another_uid_prints_nothing_of_a_file_it_cannot_read():
    tmp = _open_dir()
    d = Daemon(tmp, make_config(tmp), "--socket-mode", "0666")
    try:
        d.wait_notify("READY=1")
        secret = tmp / "web-token"
        secret.write_text(SECRET + "\n")
        secret.chmod(0o600)                           # root's; nobody may not read it
        r = _as_nobody("ctl", "--socket", d.sock, "load", str(secret), cwd=tmp)
        assert r.returncode == 2, (r.stdout, r.stderr)
        assert SECRET[:4] not in r.stdout + r.stderr, r.stderr
        assert "ermission denied" in r.stderr, r.stderr
        assert r.stderr.count("\n") == 1, r.stderr        # one line
        # a file it may read but is no controller: refused naming the file, not quoting it
        host = Path("/etc/hostname")
        if host.is_file() and host.read_text().strip():
            r = _as_nobody("ctl", "--socket", d.sock, "load", str(host), cwd=tmp)
            assert r.returncode == 2 and str(host) in r.stderr, r.stderr
            assert host.read_text().strip() not in r.stderr, r.stderr
        # the daemon's socket spoken to directly by that uid with the path alone: the
        # daemon does not open it for the client (its rights never read for another's)
        r = _as_nobody("raw", d.sock, str(secret), cwd=tmp)
        reply = json.loads(r.stdout)
        assert reply["ok"] is False and "content is missing" in reply["error"], reply
        assert SECRET[:4] not in r.stdout
        st = d.ctl_json("status")
        assert not st["controller"]["loaded"], st["controller"]
    finally:
        d.stop()
        shutil.rmtree(tmp, ignore_errors=True)


def _extreme_controllers(tmp: Path) -> dict[str, tuple[Path, str]]:
    """name -> (file, what its refusal says)."""
    out = {}
    huge = tmp / "b-1e300.yaml"
    huge.write_text("rigd_controller: 1\nfs_hz: 5000.0\nA: [[0.5]]\nB: [[1.0e+300, 0.0]]\n"
                    "C: [[1.0], [0.0]]\nD: [[0.0, 0.0], [0.0, 0.0]]\n")
    out["B = 1e300"] = (huge, "controller_gates.max_gain_v_per_um")
    dhuge = tmp / "d-1e300.yaml"
    dhuge.write_text("rigd_controller: 1\nfs_hz: 5000.0\nA: [[0.5]]\nB: [[0.0, 0.0]]\n"
                     "C: [[0.0], [0.0]]\nD: [[1.0e+300, 0.0], [0.0, 0.0]]\n")
    out["D = 1e300"] = (dhuge, "controller_gates.max_gain_v_per_um")
    nan = tmp / "nan.yaml"
    nan.write_text("rigd_controller: 1\nfs_hz: 5000.0\nA: [[0.5]]\nB: [[.nan, 0.0]]\n"
                   "C: [[1.0], [0.0]]\nD: [[0.0, 0.0], [0.0, 0.0]]\n")
    out["NaN"] = (nan, "NaN")
    # the shipped design with its sign flipped and its design plant taken out: a stable
    # K∞(z) within the gain bound whose closed loop on the rig is unstable
    k = yaml.safe_load((ROOT / "config" / "controller.yaml").read_text())
    flipped = tmp / "unstable-no-design-plant.yaml"
    doc = {key: k[key] for key in ("rigd_controller", "fs_hz", "A", "B", "C", "D")}
    doc["C"] = (-np.asarray(k["C"])).tolist()
    flipped.write_text(yaml.safe_dump(doc))
    out["unstable closed loop, no design_plant"] = (flipped, "unstable on the nominal plant")
    return out


def test_extreme_controllers_are_refused_by_ctl_load_and_the_web_upload(tmp_path):
    import httpx2 as httpx
    from webproc import daemon_and_web

    bad = _extreme_controllers(tmp_path)
    with daemon_and_web(tmp_path) as (d, web), \
            httpx.Client(base_url=web.url, timeout=120, headers=web.auth()) as http:
        before = d.ctl_json("status")["controller"]
        assert before["loaded"], before
        for name, (path, says) in bad.items():
            r = d.ctl("load", str(path), check=False)
            assert r.returncode == 2, (name, r.stdout, r.stderr)
            assert says in r.stderr and r.stderr.count("\n") == 1, (name, r.stderr)
            up = http.post("/api/load", json={"upload": {"name": path.name,
                                                         "text": path.read_text()}})
            assert up.status_code in (400, 409), (name, up.status_code, up.text)
            assert says in up.json()["error"], (name, up.text)
        # nothing of them reached the loop: the controller it had still runs
        after = d.ctl_json("status")
        assert after["controller"]["source"] == before["source"], after["controller"]
        assert after["fault"]["code"] == 0, after["fault"]
        # the shipped controller (with its design plant) passes the same gates
        r = d.ctl("load", str(ROOT / "config" / "controller.yaml"), check=False)
        assert r.returncode == 0, r.stderr


def _serial_config(tmp: Path, link: str) -> Path:
    return make_config(
        tmp, drivers={"fast": {"name": "serial", "options": {
            "port": link, "reconnect_s": 0.05, "timeout_ms": 5000.0, "fault_on_gap": False}},
            "slow": []},
        supervisor={"stale_frames": 0, "valve_error_s": 1000.0},
        clock={"overrun": "catch_up"})


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in ``mask``."""
    m = np.concatenate([[False], mask, [False]]).astype(int)
    edges = np.flatnonzero(np.diff(m))
    return list(zip(edges[::2], edges[1::2], strict=True))


def test_serial_frontend_killed_2s_records_ex_invalid_and_names_the_disconnect():
    tmp = _open_dir()         # the record is large: removed however it ends
    try:
        _serial_frontend_killed_2s_records_ex_invalid_and_names_the_disconnect(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _serial_frontend_killed_2s_records_ex_invalid_and_names_the_disconnect(tmp):
    from emuproc import EmulatorProcess

    link = str(tmp / "frontend")
    emu = EmulatorProcess(link, fs=5000.0, hold_timeout=0.5, tx_buffer_s=0.5,
                          late_drop_s=0.002)
    rec = tmp / "serial.h5"
    d = Daemon(tmp, _serial_config(tmp, link), "--record", str(rec))
    try:
        d.wait_notify("READY=1")
        # frames on disk before the fault, the last ones valid (a fault latched by the
        # busy start is reset: the outage must be what the record shows)
        d.ctl("reset")
        _wait(lambda: _settled(rec, 5000), what="valid frames flushed before the fault")
        flushed = _n_frames(rec)
        emu._proc.kill()                 # the front-end dies: its pty closes
        emu._proc.join(10)
        time.sleep(2.0)                  # the outage the test injects
        emu = EmulatorProcess(link, fs=5000.0, hold_timeout=0.5, tx_buffer_s=0.5,
                              late_drop_s=0.002)
        # back: the driver reconnects by itself and valid frames flow again
        _wait(lambda: _frames_after_outage(rec), what="valid frames after the outage")
        faults = d.ctl_json("faults")["faults"]
    finally:
        d.stop()
        emu.stop()
    fr = _frames(rec)
    assert len(fr) >= flushed, (len(fr), flushed)
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1), "recorded frames are contiguous"
    names = [f["name"] for f in faults]
    assert "driver_status" in names, faults
    text = next(f["text"] for f in faults if f["name"] == "driver_status")
    assert "disconnected" in text and "status bits" not in text, text
    ex = fr[:, REC["e_x"]]
    bad = ~np.isfinite(ex)
    runs = _runs(bad)
    assert runs, "the outage is in the record as invalid samples"
    start, stop = max(runs, key=lambda r: r[1] - r[0])
    t = fr[:, REC["t"]]
    assert t[stop - 1] - t[start] >= 1.5, (t[start], t[stop - 1])    # ~2 s, invalid
    assert start >= flushed - 1, "no invalid sample before the fault"
    held = ex[start - 1]
    assert np.isfinite(held) and not np.any(ex[start:stop] == held), "never the held value"
    # the other sensor channels of the front-end likewise; the fault column marks the reason
    for ch in ("e_y", "y_p1", "phi"):
        assert np.all(np.isnan(fr[start:stop, REC[ch]])), ch
    assert np.all(fr[start:stop, REC["fault"]] != 0)
    assert np.all(np.isfinite(fr[stop:, REC["e_x"]])), "valid again once reconnected"


def _frames_after_outage(rec) -> bool:
    return _valid_after_nan(rec, "e_x")


def test_plc_killed_and_back_records_p_inj_invalid_and_names_the_loss():
    tmp = _open_dir()         # the record is large: removed however it ends
    try:
        _plc_killed_and_back_records_p_inj_invalid_and_names_the_loss(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _plc_killed_and_back_records_p_inj_invalid_and_names_the_loss(tmp):
    from modbus_server import PlcServer

    plc = PlcServer(p_inj_bar=4.0, omega_rpm=0.0).start()
    port = plc.port
    rec = tmp / "plc.h5"
    cfg = make_config(tmp, drivers={"fast": {"name": "sim"}, "slow": [
        # generous device timeouts: the PLC stand-in is a thread of this (busy) test process
        {"name": "modbus", "poll_hz": 20.0,
         "options": {"host": "127.0.0.1", "port": port, "timeout_s": 2.0,
                     "reconnect_s": 0.1, "failures_to_fault": 3}}]},
        supervisor={"slow_stale_s": 10.0})
    d = Daemon(tmp, cfg, "--record", str(rec))
    try:
        d.wait_notify("READY=1")
        d.ctl("reset")
        _wait(lambda: (lambda f: f is not None and np.all(f[:, REC["p_inj_bar"]] == 4.0))(
            _settled(rec, 5000)), what="frames with the PLC's P_I flushed before the fault")
        flushed = _n_frames(rec)
        plc.stop()                        # the PLC goes away
        _wait(lambda: any(f["name"] == "slow_driver"
                          for f in d.ctl_json("faults")["faults"]), what="the loss latched")
        time.sleep(2.0)                   # the outage the test injects
        plc = PlcServer(port=port, p_inj_bar=4.0, omega_rpm=0.0).start()
        _wait(lambda: _valid_after_nan(rec, "p_inj_bar"), what="P_I valid again")
        faults = d.ctl_json("faults")["faults"]
    finally:
        d.stop()
        plc.stop()
    fr = _frames(rec)
    assert len(fr) >= flushed, (len(fr), flushed)
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1), "recorded frames are contiguous"
    loss = [f for f in faults if f["name"] == "slow_driver"]
    assert loss, faults
    assert "modbus" in loss[0]["text"] and "127.0.0.1" in loss[0]["text"], loss[0]
    p = fr[:, REC["p_inj_bar"]]
    runs = _runs(~np.isfinite(p))
    assert runs, "the outage is in the record as invalid samples"
    start, stop = max(runs, key=lambda r: r[1] - r[0])
    t = fr[:, REC["t"]]
    assert t[stop - 1] - t[start] >= 1.5, (t[start], t[stop - 1])
    assert start >= flushed - 1
    assert not np.any(p[start:stop] == 4.0), "never the held 4.0"
    assert np.all(np.isfinite(fr[start:stop, REC["e_x"]])), "the fast channels stay valid"
    assert np.all(p[stop:] == 4.0), "valid again once the PLC answers"


def _valid_after_nan(rec, ch) -> bool:
    """The outage (NaN in ``ch``) and 2500 valid frames after it are on disk."""
    fr = _frames(rec, last=60000)
    if fr is None:
        return False
    bad = np.flatnonzero(~np.isfinite(fr[:, REC[ch]]))
    return bool(bad.size) and len(fr) - bad[-1] > 2500


def test_a_dead_daemon_is_exit_3_and_safe_says_not_taken(tmp_path):
    """kill -9 of the daemon: a client connected to it gets ``the daemon ended`` (exit
    status 3 for the CLI, not the bad-input 2), and ``rigd ctl safe`` says at once that SAFE
    was NOT taken (the SAFE word's daemon is gone: nothing will take the request)."""
    import signal

    from rigd.errors import EXIT_DAEMON_GONE, DaemonGone
    from rigd.service.client import ControlClient

    d = Daemon(tmp_path, make_config(tmp_path))
    try:
        d.wait_notify("READY=1")
        client = ControlClient(d.sock, timeout=60).connect()
        assert client.call("ping")["pong"]
        kids = [pid for pid, _, _ in d.processes() if pid != d.proc.pid]
        d.proc.send_signal(signal.SIGKILL)
        d.proc.wait(60)
        for pid in kids:             # its socket process ends with it (the connection closes)
            _wait(lambda pid=pid: not Path(f"/proc/{pid}").exists()
                  or "Z" in Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1][:3],
                  what=f"child {pid} to end")
        with pytest.raises(DaemonGone, match="the daemon ended"):
            client.request("status")
        client.close()
        t0 = time.monotonic()
        r = subprocess.run([RIGD, "ctl", "--socket", d.sock, "--timeout", "300", "safe"],
                           capture_output=True, text=True, timeout=PROCESS_S)
        waited = time.monotonic() - t0
        assert r.returncode == EXIT_DAEMON_GONE, (r.stdout, r.stderr)
        assert "SAFE was NOT taken" in r.stderr and r.stderr.count("\n") == 1, r.stderr
        assert waited < 300, "it did not wait for the SAFE word's deadline"
    finally:
        d.stop()
