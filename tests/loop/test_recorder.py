"""Recorder: 10^6 lock-step frames to HDF5 without a gap; a SIGKILLed recording stays readable."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from loop_helpers import make_plant

from rigd.frame import REC, RECORD_NAMES
from rigd.loop.loop import ControlLoop
from rigd.loop.sinks import RecordSpec
from rigd.recording.h5sink import open_recording
from rigd.rigconfig import default_config

ROOT = Path(__file__).resolve().parents[2]
RIGD = [sys.executable, "-c", "import sys; from rigd.cli import main; sys.exit(main())"]


def test_million_lockstep_frames_recorded_without_gap(tmp_path):
    # a small ring forces the lock-step runner to wait for the writer thread many times
    cfg = default_config(clock={"mode": "lockstep"}, recorder={"ring_frames": 1 << 15})
    loop = ControlLoop(cfg, make_plant())
    path = tmp_path / "big.h5"
    n = 1_000_000
    with loop:
        loop.run_cycles(123)
        res = loop.run_segment(np.zeros((n, 2)), record=RecordSpec(path, {"kind": "bench"}))
        assert loop.status()["recorder"]["dropped"] == 0
    assert res.n_frames == n and res.first_seq == 123
    with open_recording(path) as f:
        ds = f["frames"]
        assert ds.shape == (n, len(RECORD_NAMES))
        assert list(ds.attrs["channels"]) == list(RECORD_NAMES)
        seq = ds[:, REC["seq"]]
        assert f.attrs["kind"] == "bench" and f.attrs["fs"] == 5000.0
        assert "loop:" in f.attrs["config"] and f.attrs["rigd_version"]
        tail = ds[-1000:]
    assert seq[0] == 123 and np.all(np.diff(seq) == 1)
    assert np.all(np.isfinite(tail))


def test_sigkilled_recording_is_readable_up_to_last_flush(tmp_path):
    cfg_path = tmp_path / "sim.yaml"
    doc = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    doc["recorder"]["flush_interval_s"] = 0.1
    doc["clock"]["mode"] = "realtime"
    cfg_path.write_text(yaml.safe_dump(doc))
    rec = tmp_path / "killed.h5"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    child = subprocess.Popen([*RIGD, "run", "--config", str(cfg_path),
                              "--record", str(rec)], cwd=ROOT, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        seen = 0
        deadline = time.monotonic() + 60
        while seen < 3000 and time.monotonic() < deadline:   # 0.6 s of frames flushed
            time.sleep(0.2)
            assert child.poll() is None, child.stderr.read().decode()
            if rec.exists():
                try:
                    with open_recording(rec) as f:
                        seen = f["frames"].shape[0]
                except OSError:
                    pass
        assert seen >= 3000
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(10)
    assert child.returncode == -signal.SIGKILL
    with open_recording(rec) as f:
        frames = f["frames"][:]
        assert f.attrs["fs"] == 5000.0
    assert len(frames) >= seen
    seq = frames[:, REC["seq"]]
    assert np.all(np.diff(seq) == 1)
    assert np.all(np.isfinite(frames[:, REC["e_x"]]))


def test_memory_and_file_sinks_get_identical_frames(tmp_path):
    cfg = default_config(clock={"mode": "lockstep"})
    exc = np.random.default_rng(0).uniform(-1, 1, (3000, 2))
    out = []
    for rec in ("memory", tmp_path / "a.h5"):
        loop = ControlLoop(cfg, make_plant())
        with loop:
            res = loop.run_segment(exc, record=rec, pre=10, post=10)
        if res.frames is not None:
            out.append(res.frames)
        else:
            with open_recording(res.path) as f:
                out.append(f["frames"][:])
    np.testing.assert_array_equal(out[0], out[1])
    assert len(out[0]) == 3020


def test_failed_recording_latches_fault_loop_goes_on_file_keeps_flushed_frames(tmp_path):
    """The writer process under a file-size limit (a full disk as it sees it: EFBIG)."""
    import resource

    from rigd.loop import faults as FC

    cfg = default_config(clock={"mode": "lockstep", "batch_cycles": 4096},
                         recorder={"flush_interval_s": 0.05})
    loop = ControlLoop(cfg, make_plant())
    path = tmp_path / "full.h5"
    with loop:
        sink = loop.start_recording(path)
        pid = loop.status()["recorder"]["writer_pid"]
        loop.run_cycles(5000)
        end = time.monotonic() + 600                 # a hang bound: waits on the flush
        while sink.n_flushed < 5000 and time.monotonic() < end:
            time.sleep(0.01)
        assert sink.n_flushed == 5000
        limit = path.stat().st_size + (1 << 20)       # ~4 000 frames more of 31 channels
        resource.prlimit(pid, resource.RLIMIT_FSIZE, (limit, limit))
        loop.run_cycles(55000)
        with pytest.raises(OSError, match=r"File too large \(errno 27\)") as e:
            loop.stop_recording(sink)
        assert str(e.value).startswith(
            f"recording {path} failed: File too large (errno 27); the file keeps every frame "
            f"up to the last flush ({sink.n_flushed} frames, seq 0..{sink.n_flushed - 1})")
        loop.run_cycles(1000)                    # the loop goes on, in the safe state
        st = loop.status()
    assert st["fault"]["code"] == FC.RECORDER_OVERFLOW and st["seq"] == 61000
    assert path.stat().st_size <= limit
    seq = _seq_of(path)
    assert len(seq) >= sink.n_flushed >= 5000 and np.all(np.diff(seq) == 1) and seq[0] == 0


def _seq_of(path):
    with open_recording(path) as f:
        return f["frames"][:, REC["seq"]]
