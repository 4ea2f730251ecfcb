"""The daemon (the loop's process) writes no HDF5: its writer process does (real processes,
real files).

* ``rigd run --record`` plus an experiment: the daemon's memory maps no h5py/libhdf5 module,
  the writer process's do; the experiment's record and the main recording are complete;
* the writer process SIGKILLed while ``--record`` runs: ``recorder_overflow`` latched, the loop
  keeps cycling, the daemon answers, and ``rigd run`` exits 1 with one line naming the file,
  the writer's end and what the file keeps, which reads back contiguous.
"""

import os
import re
import signal

import numpy as np
import yaml
from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import read_frames, wait_for

from rigd.data import load_record
from rigd.data.manifest import read_manifest
from rigd.frame import REC
from rigd.loop import faults as FC

PRBS = {"kind": "prbs", "name": "short-prbs", "operating_point": {"omega_rpm": 0,
                                                                  "p_inj_bar": 4.0},
        "amplitude_v": 0.3, "seed": 3, "duration_s": 0.5, "lead_in_s": 0.1}


def _maps_hdf5(pid):
    """The HDF5 libraries (h5py's extension modules, libhdf5) mapped into process ``pid``."""
    with open(f"/proc/{pid}/maps") as f:
        return sorted({line.split()[-1] for line in f
                       if re.search(r"h5py|libhdf5", line.split()[-1] if line.split() else "")})


def _n_flushed(path):
    """Frames readable in a live recording (0 before its first flush)."""
    try:
        return len(read_frames(path)) if path.exists() else 0
    except OSError:
        return 0


def test_daemon_maps_no_hdf5_while_recording_and_running_an_experiment(tmp_path):
    cfg = make_config(tmp_path, clock={"spin_us": 0.0})
    spec = tmp_path / "prbs.yaml"
    spec.write_text(yaml.safe_dump(PRBS))
    run = tmp_path / "runs" / "run"
    rec = tmp_path / "rec.h5"
    d = Daemon(tmp_path, cfg, "--record", str(rec))
    try:
        d.wait_notify("READY=1")
        d.ctl("start", str(spec), "--run-dir", str(run))
        assert wait_for(lambda: d.ctl_json("experiment")["state"] not in ("starting",
                                                                          "running"),
                        PROCESS_S)
        exp = d.ctl_json("experiment")
        writer = d.writer_pid()
        assert writer is not None and writer != d.proc.pid
        in_daemon, in_writer = _maps_hdf5(d.proc.pid), _maps_hdf5(writer)
    finally:
        code, _ = d.stop()
    assert code == 0, d.log()
    assert exp["state"] == "complete", exp
    assert in_daemon == [], in_daemon
    assert any("h5py" in m for m in in_writer), in_writer
    man = read_manifest(run)
    assert man["status"] == "complete" and len(man["files"]) == 1
    f = man["files"][0]
    r = load_record(run / f["path"])
    assert r.n == f["n_frames"] == int(0.6 * 5000)
    assert not list(run.glob("*.part"))
    fr = read_frames(rec)
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1)


def test_writer_killed_in_the_daemon_loss_reported_loop_cycles_exit_1(tmp_path):
    cfg = make_config(tmp_path, clock={"spin_us": 0.0}, recorder={"flush_interval_s": 0.1})
    rec = tmp_path / "rec.h5"
    d = Daemon(tmp_path, cfg, "--record", str(rec))
    try:
        d.wait_notify("READY=1")
        writer = d.writer_pid()
        seq0 = d.ctl_json("status")["seq"]
        # frames flushed to the file before the kill (waited for, not slept)
        assert wait_for(lambda: _n_flushed(rec) > 1000, PROCESS_S)
        os.kill(writer, signal.SIGKILL)
        assert wait_for(lambda: d.ctl_json("status")["fault"]["code"] != 0, PROCESS_S)
        st = d.ctl_json("status")
        assert wait_for(lambda: d.ctl_json("status")["seq"] > st["seq"], PROCESS_S)
        st2 = d.ctl_json("status")
    finally:
        code, _ = d.stop(signal.SIGTERM)
    log = (tmp_path / "daemon.err").read_text()
    assert st["fault"]["code"] == FC.RECORDER_OVERFLOW and st["seq"] > seq0
    assert st2["recorder"]["writer_pid"] is None
    assert code == 1, log[-2000:]
    m = re.search(r"rigd run: recording (\S+) failed: the writer process ended \(killed by "
                  r"SIGKILL\); the file keeps every frame up to the last flush \((\d+) frames, "
                  r"seq (\d+)\.\.(\d+)\)", log)
    assert m, log[-2000:]
    assert m.group(1) == str(rec) and "Traceback" not in log
    fr = read_frames(rec)
    seq = fr[:, REC["seq"]]
    assert len(fr) >= int(m.group(2)) > 1000 and seq[0] == int(m.group(3))
    assert np.all(np.diff(seq) == 1)
