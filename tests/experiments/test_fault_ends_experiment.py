"""A latched fault ends the experiment at once (lock-step; the daemon process:
tests/service/test_experiment_fault_process.py).

Before, the segment played on to its planned end in the safe state and a sweep went on to
its next points: the experiment stayed "running" for the rest of its plan after ``safe`` or
any latched fault. Now the segment ends at the fault's cycle, the run is ``failed`` with the
fault named in the manifest (and the manager's status), the record is closed and readable,
and the next experiment starts once the fault is reset.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigd.data import load_record
from rigd.data.manifest import read_manifest
from rigd.errors import InputError
from rigd.experiments.runner import run_experiment
from rigd.loop.app import build_loop
from rigd.rigconfig import default_config
from rigd.service.experiment_host import ExperimentHost as ExperimentManager

FS = 5000.0
# a 300 N hit drives the shaft beyond the allowed fraction of the film gap: the supervisor
# latches shaft_displacement a few ms after the hit, 2 s before the record's planned end
HARD_HIT = {"kind": "impact", "axis": "x", "controller": [False], "repeats": 2,
            "pre_s": 0.01, "post_s": 2.0, "spacing_s": 0.0, "peak_n": 300.0,
            "pulse_s": 0.001}
SWEEP = {"kind": "sweep", "grid": {"omega_rpm": [0, 1000, 2000], "p_inj_bar": [4.0]},
         "settle": {"hold_s": 0.02}, "at_each": HARD_HIT}
SHORT = {"kind": "prbs", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
         "amplitude_v": 0.5, "duration_s": 0.2, "lead_in_s": 0.02}


def _check_failed_run(data, run_dir):
    assert data["status"] == "failed"
    fault = data["fault"]
    assert fault["name"] == "shaft_displacement" and fault["code"] > 0
    assert "shaft_displacement" in data["message"]
    p0 = data["points"][0]
    assert p0["status"] == "failed" and "shaft_displacement" in p0["error"]
    # ended at once: not the second repeat, not the next points
    assert [p["status"] for p in data["points"][1:]] == ["missing"] * (len(data["points"]) - 1)
    assert data["missing"] == [p["index"] for p in data["points"]]
    (f,) = data["files"]
    assert f["point"] == 0 and not list(run_dir.rglob("*.part"))
    rec = load_record(run_dir / f["path"])              # closed and readable
    planned = int((HARD_HIT["pre_s"] + HARD_HIT["post_s"]) * FS)
    assert rec.n == f["n_frames"] < planned // 4
    fcol = rec.col("fault")
    assert fcol[-1] == fault["code"] and np.all(fcol[:-1] == 0)   # ends at the fault's cycle
    assert rec.col("seq")[-1] == fault["seq"]
    assert np.all(np.diff(rec.col("seq")) == 1)


def test_fault_ends_the_sweep_at_once_and_names_the_fault(tmp_path):
    with build_loop(default_config(), clock="lockstep") as lp:
        man = run_experiment(SWEEP, lp, tmp_path / "run")
        data = read_manifest(tmp_path / "run")
        assert man.status == "failed" and man.fault == data["fault"]
        _check_failed_run(data, tmp_path / "run")
        # while the fault is latched an experiment is refused before anything is made
        with pytest.raises(InputError, match="shaft_displacement is latched"):
            run_experiment(SHORT, lp, tmp_path / "run2")
        assert not (tmp_path / "run2").exists()
        lp.run_cycles(2500)               # the shaft settles in the safe state, then reset
        lp.reset_fault()
        lp.run_cycles(1)                  # a reset takes effect at the next cycle boundary
        man2 = run_experiment(SHORT, lp, tmp_path / "run3")
    assert man2.status == "complete" and man2.fault is None


def test_manager_reports_the_fault_and_starts_the_next_experiment(tmp_path):
    with build_loop(default_config(), clock="lockstep") as lp:
        mgr = ExperimentManager(lp, runs_root=tmp_path / "runs")
        mgr.start(spec=SWEEP, run_dir=str(tmp_path / "runs" / "a"))
        mgr.join(120)
        st = mgr.status()
        assert st["state"] == "failed" and st["fault"]["name"] == "shaft_displacement", st
        assert "shaft_displacement" in st["message"]
        _check_failed_run(read_manifest(tmp_path / "runs" / "a"), tmp_path / "runs" / "a")
        with pytest.raises(InputError, match="is latched"):
            mgr.start(spec=SHORT, run_dir=str(tmp_path / "runs" / "b"))
        lp.run_cycles(2500)
        lp.reset_fault()
        lp.run_cycles(1)
        mgr.start(spec=SHORT, run_dir=str(tmp_path / "runs" / "c"))
        mgr.join(120)
        st = mgr.status()
    assert st["state"] == "complete" and st.get("fault") is None, st
    c = tmp_path / "runs" / "c"
    rec = load_record(c / read_manifest(c)["files"][0]["path"])
    assert np.all(rec.col("fault") == 0) and np.any(rec.col("x_x") != 0)
