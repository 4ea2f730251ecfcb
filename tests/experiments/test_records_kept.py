"""A record cut short is kept, marked incomplete and listed; a dead process's run is
recovered on start (real loop lock-step, real HDF5 files, a real process killed mid-write)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from rigd.data.manifest import read_manifest
from rigd.experiments.recovery import recover_runs
from rigd.experiments.runner import run_experiment
from rigd.frame import N_REC, REC
from rigd.loop.app import build_loop
from rigd.owner import PROCESS_ENDED, stale_runs
from rigd.recording.h5sink import open_recording
from rigd.rigconfig import default_config
from rigd.web.runs import summarize

FS = 5000.0
PRBS = {"kind": "prbs", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
        "amplitude_v": 0.3, "duration_s": 1.0, "lead_in_s": 0.1}


@pytest.fixture(scope="module")
def loop():
    lp = build_loop(default_config(), clock="lockstep")
    with lp:
        yield lp


class _Interrupting:
    """A loop whose segment is interrupted (SIGINT's KeyboardInterrupt) at cycle ``at``: the
    real loop plays and records until then."""

    def __init__(self, loop, at):
        self._loop, self._at = loop, at

    def __getattr__(self, name):
        return getattr(self._loop, name)

    def run_segment(self, exc, *, events=(), **kw):
        if not hasattr(kw.get("record"), "path"):      # not a file recording
            return self._loop.run_segment(exc, events=events, **kw)

        def interrupt():
            raise KeyboardInterrupt

        return self._loop.run_segment(exc, events=[*events, (self._at, interrupt)], **kw)


def test_sigint_mid_record_keeps_it_listed_and_marked_incomplete(loop, tmp_path):
    man = run_experiment(PRBS, _Interrupting(loop, 2000), tmp_path / "run")
    data = read_manifest(tmp_path / "run")
    assert man.status == data["status"] == "interrupted"
    (f,) = data["files"]
    assert f["complete"] is False and f["incomplete_reason"] == "interrupted by SIGINT", f
    with open_recording(tmp_path / "run" / f["path"]) as h:
        n = h["frames"].shape[0]
        assert not h.attrs["complete"] and h.attrs["incomplete_reason"] == \
            "interrupted by SIGINT" and h.attrs["n_frames"] == n
    # every cycle played before the interrupt is on disk
    assert f["n_frames"] == n and 2000 <= n < int(1.1 * FS)
    assert data["points"][0]["status"] == "missing" and not data["points"][0]["recording"]
    assert not list((tmp_path / "run").glob("*.part")) and data["owner"]["pid"] == os.getpid()


def test_a_complete_record_says_so(loop, tmp_path):
    run_experiment({**PRBS, "duration_s": 0.2}, loop, tmp_path / "run")
    (f,) = read_manifest(tmp_path / "run")["files"]
    assert "complete" not in f
    with open_recording(tmp_path / "run" / f["path"]) as h:
        assert h.attrs["complete"] and h.attrs["incomplete_reason"] == ""
        assert h.attrs["n_frames"] == h["frames"].shape[0] == f["n_frames"] == int(0.3 * FS)


WRITER = """
import os, sys
import numpy as np
from rigd.recording.h5sink import H5Sink
s = H5Sink(sys.argv[1], fs=5000.0, meta={"kind": "prbs", "point": 0}, n_expected=100000)
for i in range(5):
    b = np.zeros((1000, {n})); b[:, {seq}] = np.arange(i * 1000, (i + 1) * 1000)
    s.write(b)
s.flush()
b = np.zeros((1000, {n})); s.write(b)        # written, never flushed
print(s.n_flushed, flush=True)
os._exit(9)                                   # killed mid-recording
""".replace("{n}", str(N_REC)).replace("{seq}", str(REC["seq"]))


def test_recovery_replays_a_dead_process_run(tmp_path):
    root = tmp_path / "runs"
    run = root / "dead"
    run.mkdir(parents=True)
    part = run / "p000_w0_p4_prbs.h5.part"
    w = subprocess.run([sys.executable, "-c", WRITER, str(part)], capture_output=True,
                       text=True, timeout=600)
    assert w.returncode == 9, w.stderr
    flushed = int(w.stdout)
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, timeout=600)
    man = {"rigd_manifest": 1, "status": "running", "experiment": {"name": "dead"},
           "owner": {"host": os.uname().nodename, "pid": int(gone.stdout), "start_ticks": 1},
           "points": [{"index": 0, "omega_rpm": 0.0, "p_inj_bar": 4.0, "status": "running",
                       "files": [], "recording": part.name}], "files": [], "missing": [0]}
    (run / "manifest.json").write_text(json.dumps(man))
    alive = root / "alive"
    alive.mkdir()
    (alive / "manifest.json").write_text(json.dumps({**man, "owner": {
        "host": os.uname().nodename, "pid": os.getpid()}}))
    assert stale_runs(root) == [run]
    (got,) = recover_runs(root)
    data = read_manifest(run)
    assert got["status"] == data["status"] == PROCESS_ENDED and data["recovered"]
    (f,) = data["files"]
    assert f["path"] == "p000_w0_p4_prbs.h5" and f["point"] == 0 and f["kind"] == "prbs"
    assert f["complete"] is False and f["incomplete_reason"] and not part.exists()
    with open_recording(run / f["path"]) as h:
        fr = h["frames"][:]
        assert not h.attrs["complete"]
    assert len(fr) == f["n_frames"] >= flushed == 5000
    assert np.all(np.diff(fr[:5000, REC["seq"]]) == 1)
    assert data["points"][0]["status"] == "missing"
    assert data["points"][0]["files"] == [f["path"]] and data["points"][0]["recording"] is None
    assert "p000_w0_p4_prbs.h5" in data["message"]
    runs_tab = summarize(run)                  # the web console's Runs tab
    assert runs_tab["status"] == PROCESS_ENDED and runs_tab["incomplete"] == [f["path"]]
    assert runs_tab["records"] == [f["path"]]
    assert read_manifest(alive)["status"] == "running"       # a live owner's run: untouched
    assert stale_runs(root) == [] and recover_runs(root) == []


def test_a_zombie_owner_is_gone():
    """An owner killed but not yet reaped (a zombie: after a crash, its dead parent's
    orphans wait for init) never writes its journal again: its run is recovered, not left
    'running' for the daemon's whole life."""
    import signal
    import time
    from pathlib import Path

    from rigd.owner import alive, start_ticks

    child = subprocess.Popen(["sleep", "60"])
    owner = {"host": os.uname().nodename, "pid": child.pid,
             "start_ticks": start_ticks(child.pid)}
    try:
        assert alive(owner)
        os.kill(child.pid, signal.SIGKILL)
        # not reaped yet: wait until the kernel shows it as a zombie
        stat = Path(f"/proc/{child.pid}/stat")
        deadline = time.monotonic() + 60
        while stat.read_text().rsplit(")", 1)[1].split()[0] != "Z":
            assert time.monotonic() < deadline
            time.sleep(0.01)
        assert not alive(owner)
    finally:
        child.wait()
