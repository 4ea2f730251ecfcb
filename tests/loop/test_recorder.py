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
from rigd.loop.sinks import RecordSpec, open_recording
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
    from rigd.loop import faults as FC
    from rigd.loop.sinks import H5Sink

    class FailingSink(H5Sink):
        """Fails like a full disk once 20000 frames are in (after flushing them)."""

        def write(self, block):
            # the disk fills at frame 20000 whatever the writer's block sizes are (one block of
            # all 60000 frames when the writer thread first wakes after the batch)
            room = 20000 - self.n_written
            if len(block) > room:
                if room > 0:
                    super().write(block[:room])
                self.flush()
                raise OSError(28, "No space left on device")
            super().write(block)

    cfg = default_config(clock={"mode": "lockstep", "batch_cycles": 4096})
    loop = ControlLoop(cfg, make_plant())
    path = tmp_path / "full.h5"
    with loop:
        sink = loop.recorder.add_sink(FailingSink(path, fs=5000.0))
        sink.first_seq = int(loop.status()["seq"])
        loop.run_cycles(60000)
        loop.recorder.drain()
        with pytest.raises(OSError, match="No space"):
            loop.stop_recording(sink)
        loop.run_cycles(1000)                    # the loop goes on, in the safe state
        st = loop.status()
    assert st["fault"]["code"] == FC.RECORDER_OVERFLOW and st["seq"] == 61000
    with open_recording(path) as f:
        seq = f["frames"][:, REC["seq"]]
    assert len(seq) >= 20000 and np.all(np.diff(seq) == 1) and seq[0] == 0
