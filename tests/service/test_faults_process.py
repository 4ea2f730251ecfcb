"""Fault injection where the fault is about the process: SIGTERM in the middle of an
experiment, and the disk filling up while recording (see also test_daemon_process.py for the
bad controller on SIGHUP)."""

import json
import re
import signal
import time

import h5py
import numpy as np
import pytest
from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import assert_safe_after_fault, controller_file, read_frames, wait_for

from rigd.frame import REC
from rigd.loop import faults as FC

EXPERIMENT = """\
kind: prbs
name: long-prbs
operating_point: {omega_rpm: 0, p_inj_bar: 4.0}
amplitude_v: 0.3
seed: 3
duration_s: 30.0
lead_in_s: 0.1
controller: true
"""


def test_sigterm_during_experiment(tmp_path):
    cfg = make_config(tmp_path, clock={"spin_us": 0.0})
    ctrl = controller_file(tmp_path)
    spec = tmp_path / "long.yaml"
    spec.write_text(EXPERIMENT)
    main_rec = tmp_path / "main.h5"
    d = Daemon(tmp_path, cfg, "--record", str(main_rec), "--controller", str(ctrl))
    try:
        d.wait_notify("READY=1")
        started = d.ctl_json("start", str(spec), "--run-dir", str(tmp_path / "runs" / "run"))
        assert started["name"] == "long-prbs"
        assert wait_for(lambda: d.ctl_json("experiment")["state"] == "running", PROCESS_S)
        time.sleep(1.5)  # well inside the 30 s record
        assert d.ctl_json("experiment")["state"] == "running"
    finally:
        code, out = d.stop(signal.SIGTERM)
    assert code == 0, d.log()
    assert any("STOPPING=1" in m for m in d.messages)
    # the daemon's own recording: safe state within one cycle of the operator stop
    fr = read_frames(main_rec)
    assert_safe_after_fault(fr, FC.OPERATOR_STOP)
    # the experiment: manifest says interrupted, its record is closed, readable, contiguous,
    # and ends in the safe state too
    man = json.loads((tmp_path / "runs" / "run" / "manifest.json").read_text())
    assert man["status"] in ("interrupted", "failed"), man["status"]
    run = tmp_path / "runs" / "run"
    assert not list(run.rglob("*.part")), "no half-written file left"
    # the runner keeps completed segments only; whatever it kept is whole and contiguous, and
    # its frames are the very frames of the main recording
    for path in run.rglob("*.h5"):
        with h5py.File(path, "r") as f:
            seg = f["frames"][:]
        assert np.all(np.diff(seg[:, REC["seq"]]) == 1)
        i0 = int(seg[0, REC["seq"]] - fr[0, REC["seq"]])
        np.testing.assert_array_equal(fr[i0:i0 + len(seg)], seg)
    # the excitation was playing when SIGTERM came, and the main recording has all of it
    i = int(np.flatnonzero(fr[:, REC["fault"]])[0])
    assert np.any(fr[i - 500:i, REC["x_x"]] != 0)


@pytest.fixture(scope="module")
def disk_full(tmp_path_factory):
    """RLIMIT_FSIZE on the running daemon process, 3 MB above the recording's size at READY:
    the recording file cannot grow past it (about 2.3 s more frames). A tiny tmpfs or a full
    loopback filesystem needs root, which the test host does not give; the writer sees the
    same thing, a failing write() (EFBIG). The limit is set after start-up (prlimit): set
    before exec it also refused the ftruncate of the recorder's shared-memory ring."""
    tmp_path = tmp_path_factory.mktemp("diskfull")
    cfg = make_config(tmp_path, clock={"spin_us": 0.0}, recorder={"flush_interval_s": 0.1})
    rec = tmp_path / "rec.h5"
    d = Daemon(tmp_path, cfg, "--record", str(rec), "--controller",
               str(controller_file(tmp_path)), "--enable-controller",
               fsize_limit=True)
    seen = {}
    try:
        d.wait_notify("READY=1")
        writer = d.writer_pid()
        seen["limit"] = (rec.stat().st_size if rec.exists() else 0) + 3 * 1024 * 1024
        d.limit_fsize(seen["limit"], writer)
        seen["faulted"] = wait_for(lambda: d.ctl_json("status")["fault"]["code"] != 0, PROCESS_S)
        seen["st"] = d.ctl_json("status")
        seq = seen["st"]["seq"]          # the loop keeps cycling: waited for, not slept
        seen["cycling"] = wait_for(lambda: d.ctl_json("status")["seq"] > seq, PROCESS_S)
        seen["st2"] = d.ctl_json("status")
        seen["human"] = d.ctl("status").stdout
        seen["logged"] = wait_for(lambda: "recording failed" in d.log(), PROCESS_S)
    finally:
        seen["code"], seen["out"] = d.stop(signal.SIGTERM)
    seen["log"] = (tmp_path / "daemon.err").read_text()
    seen["rec"] = rec
    return seen


def test_disk_full_fault_latched_loop_safe_daemon_alive(disk_full):
    s = disk_full
    assert s["faulted"], s["log"][-2000:]
    assert s["st"]["fault"]["code"] == FC.RECORDER_OVERFLOW, s["st"]["fault"]
    # the daemon kept answering, the loop kept cycling, in the safe state (r = 0, K∞ off)
    assert s["cycling"] and s["st2"]["seq"] > s["st"]["seq"]
    assert s["st2"]["last_frame"]["r_x"] == 0.0 and s["st2"]["last_frame"]["r_y"] == 0.0
    # logged once (a fault of another kind latched beside it is listed, and logged, on its own)
    latched = [ln for ln in s["log"].splitlines() if '"event": "fault latched"' in ln]
    assert s["logged"] and sum('"name": "recorder_overflow"' in ln for ln in latched) == 1
    # K∞ was enabled: status and `rigd ctl status` say it is off now, tripped by the fault
    assert s["st2"]["controller"]["enabled"] is False and s["st2"]["controller"]["requested"]
    first = s["human"].splitlines()[:2]
    assert first[0].startswith("state: running") and "FAULT recorder_overflow" in first[0]
    assert first[1] == ("K∞: OFF: tripped by the fault (it was enabled; after a reset enable "
                        "it again)"), first
    assert s["rec"].stat().st_size <= s["limit"]
    assert "rigd run: recording " in s["log"]  # rigd run says so in one line on the way out


def test_disk_full_clean_exit_and_readable_recording(disk_full):
    """No crash on the way out (exit 1, not a signal), one clear line naming the file, the
    reason and what it keeps, and the file reads back with every frame up to the last flush."""
    s = disk_full
    assert s["code"] == 1, (s["code"], s["log"][-2000:])
    assert "Fatal Python error" not in s["log"] and "Segmentation" not in s["log"]
    m = re.search(r"rigd run: recording (\S+) failed: File too large "
                  r"\(errno 27\); the file keeps every frame up to the last flush \((\d+) frames, "
                  r"seq (\d+)\.\.(\d+)\)", s["log"])
    assert m, s["log"][-2000:]
    assert m.group(1) == str(s["rec"])
    n_flushed, first, last = int(m.group(2)), int(m.group(3)), int(m.group(4))
    assert n_flushed > 1000 and last - first + 1 == n_flushed
    fr = read_frames(s["rec"])
    seq = fr[:, REC["seq"]]
    assert np.all(np.diff(seq) == 1)
    assert seq[0] == first and len(fr) >= n_flushed   # nothing flushed was lost
    # the count rigd run prints is the frames on disk (it said 0 when the recording failed)
    assert f"recorded {n_flushed} frames to {s['rec']}" in s["out"], s["out"][-500:]
    # status says the recording is dead, in words, with when it died
    rec = s["st2"]["recorder"]
    assert rec["state"] == "failed" and rec["failure"]["open_ended"], rec
    assert "recorder: FAILED since" in s["human"]
