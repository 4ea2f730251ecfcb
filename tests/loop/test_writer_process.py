"""HDF5 recordings are written by a writer process of their own (rigd.recording.writer), never
in the loop's process: real processes, real files.

* the loop's process never loads h5py, even while it records;
* a run's file is complete after a normal stop (every frame of its range, in order);
* a writer killed while it records: the loop keeps cycling, the loss is a latched fault and a
  one-line error naming the file, the writer's end and what the file keeps; the file reads
  back up to its last flush; the next recording gets a fresh writer;
* a writer stopped (SIGSTOP: as slow as can be): the ring fills, every frame that finds it
  full is counted (``recorder.dropped``) and ``recorder_overflow`` latches; the loop cycles on.

Waits are on conditions (the writer's flush count, the status), bounded only as hangs.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from loop_helpers import make_plant

from rigd.frame import REC
from rigd.loop import faults as FC
from rigd.loop.loop import ControlLoop
from rigd.loop.recorder import RecordingFailed
from rigd.recording.h5sink import open_recording
from rigd.rigconfig import default_config

ROOT = Path(__file__).resolve().parents[2]
PROCESS_S = 600.0            # hang bound only (a spawned interpreter at load average 25)


def _until(pred, timeout=PROCESS_S) -> bool:
    end = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > end:
            return False
        time.sleep(0.01)
    return True


def _seq(path):
    with open_recording(path) as f:
        return f["frames"][:, REC["seq"]]


def _rt_loop(**recorder):
    cfg = default_config(clock={"mode": "realtime", "spin_us": 0.0},
                         supervisor={"overrun_storm_count": 10**9},
                         recorder={"flush_interval_s": 0.1, **recorder})
    return ControlLoop(cfg, make_plant())


def test_the_loops_process_never_loads_h5py_while_recording(tmp_path):
    code = """
import json, os, sys
import numpy as np
from rigd.loop.loop import ControlLoop
from rigd.loop.sinks import RecordSpec
from rigd.rigconfig import default_config
from rigd_drivers.sim.driver import SimPlantDriver
loop = ControlLoop(default_config(clock={"mode": "lockstep"}, recorder={"ring_frames": 4096}),
                   SimPlantDriver({"seed": 5}, fs=5000.0))
with loop:
    res = loop.run_segment(np.zeros((20000, 2)), record=RecordSpec(sys.argv[1], {"kind": "t"}))
    writer = loop.status()["recorder"]["writer_pid"]
print(json.dumps({"n": res.n_frames, "first": res.first_seq, "path": res.path,
                  "writer": writer, "me": os.getpid(), "h5py": "h5py" in sys.modules}))
"""
    rec = tmp_path / "seg.h5"
    p = subprocess.run([sys.executable, "-c", code, str(rec)], capture_output=True, text=True,
                       timeout=PROCESS_S, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["h5py"] is False                  # the writer process wrote the file
    assert out["writer"] not in (None, out["me"])
    seq = _seq(rec)
    # 20 000 frames through a 4 096-frame ring: lock-step waited for the writer process
    assert out["n"] == 20000 and len(seq) == 20000 and out["path"] == str(rec)
    assert seq[0] == out["first"] and np.all(np.diff(seq) == 1)


def test_a_runs_file_is_complete_after_a_normal_stop(tmp_path):
    loop = _rt_loop()
    path = tmp_path / "run.h5"
    with loop:
        sink = loop.start_recording(path)
        loop.start()
        assert loop.wait_cycles(5000, PROCESS_S) >= 5000
        loop.stop_recording(sink)
        st = loop.status()
    assert st["fault"]["code"] == 0 and st["recorder"]["dropped"] == 0
    seq = _seq(path)
    assert seq[0] == sink.first_seq and seq[-1] == sink.last_seq
    assert len(seq) == sink.last_seq - sink.first_seq + 1 == sink.n_written >= 5000
    assert np.all(np.diff(seq) == 1)


def test_writer_killed_loop_cycles_on_loss_is_a_fault_and_one_line(tmp_path):
    loop = _rt_loop()
    path = tmp_path / "killed.h5"
    with loop:
        sink = loop.start_recording(path)
        loop.start()
        pid = loop.status()["recorder"]["writer_pid"]
        assert pid is not None and pid != os.getpid()
        assert _until(lambda: sink.n_flushed >= 2000)        # 0.4 s of frames on disk
        os.kill(pid, signal.SIGKILL)
        assert _until(lambda: loop.status()["fault"]["code"] != 0)
        st = loop.status()
        assert st["fault"]["code"] == FC.RECORDER_OVERFLOW
        assert loop.wait_cycles(2000, PROCESS_S) >= 2000      # the loop cycles on
        with pytest.raises(RecordingFailed) as e:
            loop.stop_recording(sink)
        msg = str(e.value)
        assert msg.startswith(f"recording {path} failed: the writer process ended (killed by "
                              f"SIGKILL); the file keeps every frame up to the last flush (")
        assert "\n" not in msg
        assert loop.status()["recorder"]["writer_pid"] is None
        # the next recording gets a fresh writer and is complete
        assert loop.wait_applied(loop.reset_fault())
        sink2 = loop.start_recording(tmp_path / "after.h5")
        assert loop.status()["recorder"]["writer_pid"] not in (None, pid)
        assert loop.wait_cycles(2000, PROCESS_S) >= 2000
        loop.stop_recording(sink2)
    seq = _seq(path)
    assert len(seq) >= sink.n_flushed >= 2000 and seq[0] == sink.first_seq
    assert np.all(np.diff(seq) == 1)
    seq2 = _seq(tmp_path / "after.h5")
    assert len(seq2) == sink2.last_seq - sink2.first_seq + 1 and np.all(np.diff(seq2) == 1)


def test_writer_stopped_ring_fills_drops_counted_fault_latched_loop_cycles(tmp_path):
    loop = _rt_loop(ring_frames=4096)                    # 0.8 s at 5 kHz
    path = tmp_path / "slow.h5"
    with loop:
        sink = loop.start_recording(path)
        loop.start()
        pid = loop.status()["recorder"]["writer_pid"]
        assert _until(lambda: sink.n_flushed >= 1000)
        os.kill(pid, signal.SIGSTOP)
        try:
            assert _until(lambda: loop.status()["recorder"]["dropped"] > 0)
            st = loop.status()
            assert st["fault"]["code"] == FC.RECORDER_OVERFLOW
            assert loop.wait_cycles(2000, PROCESS_S) >= 2000  # cycling, never waiting
            st2 = loop.status()
            assert st2["recorder"]["dropped"] > st["recorder"]["dropped"]   # each one counted
        finally:
            os.kill(pid, signal.SIGCONT)
        loop.stop_recording(sink)                            # it catches up and closes
    seq = _seq(path)
    assert seq[0] == sink.first_seq and len(seq) >= 1000
    i = int(np.argmax(np.diff(seq) != 1)) + 1 if np.any(np.diff(seq) != 1) else len(seq)
    assert i >= 1000 and np.all(np.diff(seq[:i]) == 1)  # contiguous up to the first drop
