"""Honest failure of the physics-grade plant: Newton judged on the residual after the update,
non-finite solutions, floors and contact counted and reported (docs/plant.md, "Failure").

The must-show of issue 23: a 1 kN, 1 ms hammer with the supervisor's checks off ends in a
``driver_status`` fault whose text says contact, and a finite record (before, the record
reached 9.6e99 and NaN and only ``sensor_nan`` caught it).
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

from rigd.cli.ctl import format_human, status_summary
from rigd.data import load_record
from rigd.data.manifest import read_manifest
from rigd.experiments.runner import run_experiment
from rigd.frame import IN_E_X, IN_STATUS, N_IN
from rigd.loop.app import build_loop
from rigd_drivers.reynolds import analysis as an
from rigd_drivers.reynolds import kernel as k
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds.driver import ReynoldsPlantDriver

CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim_reynolds.yaml"
QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}


def _config(tmp_path, **supervisor):
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg["supervisor"].update(supervisor)
    cfg["supervisor"]["overrun_storm_count"] = 10 ** 9
    cfg["recorder"]["data_dir"] = str(tmp_path / "data")
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def _impact(peak_n):
    return {"kind": "impact", "operating_point": {"omega_rpm": 0.0, "p_inj_bar": 4.0},
            "axis": "x", "controller": [False], "repeats": 1, "pre_s": 0.01, "post_s": 0.05,
            "spacing_s": 0.0, "peak_n": peak_n, "pulse_s": 0.001}


def test_1kn_hammer_with_the_checks_off_ends_in_a_reported_contact_and_a_finite_record(
        tmp_path):
    """The real loop and experiment runner, supervisor disabled (no range, gap or tracking
    check): the journal reaches the wall within the pulse, the plant stops there, its
    ``drv_status`` latches ``driver_status`` whose text says contact — the only fault —, the
    record is finite and ``rigd ctl status`` shows the status bits and the solver's counters."""
    with build_loop(_config(tmp_path, enabled=False), clock="lockstep") as lp:
        man = run_experiment(_impact(1000.0), lp, tmp_path / "run")
        faults = lp.faults()
        st = lp.status()
    assert man.status == "failed"
    assert [f["name"] for f in faults] == ["driver_status"], faults
    assert "contact" in faults[0]["text"]
    fast = st["drivers"]["fast"]
    assert fast["name"] == "sim_reynolds" and fast["drv_status"] == L.STATUS_CONTACT
    assert fast["stopped"].startswith("contact") and fast["non_finite"] == 0
    assert 0.9 < fast["eps_max"] < 1.0            # the last sub-step before the wall (0.975)
    assert fast["newton_not_converged"] >= 1          # the sub-steps into the wall, counted
    text = status_summary(st) + "\n" + format_human(st)
    assert "FAULT driver_status" in text and "contact: the journal reached the bearing wall" \
        in text and f"drv_status: {L.STATUS_CONTACT}" in text and "newton_not_converged" in text
    data = read_manifest(tmp_path / "run")
    rec = load_record(tmp_path / "run" / data["files"][0]["path"])
    cols = np.column_stack([rec.columns[c] for c in rec.columns])
    assert np.all(np.isfinite(cols))
    assert rec.columns["f_x"].max() == pytest.approx(1000.0, rel=0.05)
    hit = np.flatnonzero(rec.columns["fault"] != 0)
    assert hit.size and np.all(rec.columns["fault"][hit[0]:] == 9)       # driver_status
    # stopped during the pulse (1 ms = 5 samples); the point's recording ends there
    t_hit = rec.columns["t"][hit[0]]
    t_hammer = rec.columns["t"][np.flatnonzero(rec.columns["f_x"] > 0)[0]]
    assert 0.0 < t_hit - t_hammer <= 0.0012
    assert 25.0 < rec.columns["e_x"][hit[0]] < 100.0        # µm at the disc, past the gap


def test_ordinary_running_is_converged_and_clean():
    """Valve steps of ±1 V on every valve and a 20 N hammer at 3 krpm: every sub-step meets
    the residual tolerance within its iterations (≈ 1.1 on average), nothing floored or
    stopped, ``drv_status`` 0."""
    d = ReynoldsPlantDriver({**QUIET, "omega_rpm": 3000.0})
    rng = np.random.default_rng(1)
    drives = 5.0 + np.repeat(rng.choice([-1.0, 1.0], size=(300, 4)), 5, axis=0)
    d.impact("x", 20.0, 1e-3)
    fr = d.run(drives)
    c = d.counters()
    assert c["substeps"] == 4 * drives.shape[0]
    assert c["newton_not_converged"] == 0 and c["non_finite"] == 0
    assert c["h_floor"] == 0 and c["p_floor"] == 0 and c["stopped"] == ""
    assert 1.0 <= c["newton_iterations"] / c["substeps"] < 1.5
    assert 0.3 < c["eps_max"] < 0.6                 # at rest under gravity: 0.43
    assert np.all(fr[:, IN_STATUS] == 0.0)


def test_non_finite_solution_stops_the_plant_and_is_counted(reynolds_run):
    """A NaN in the film (as a solver blow-up leaves it): counted, ``drv_status`` says
    diverged, the shaft stays at its last finite state, the sensors stay finite."""
    pa = an.make_arrays(QUIET)
    an.rest(pa, 5.0)
    e0 = np.zeros(N_IN)
    k.plant_sense(pa.state, pa.params, e0)
    pa.p[3] = np.nan
    fr = reynolds_run(pa, np.full((20, 4), 5.0))
    assert pa.stsc[L.ST_NAN] == 1 and pa.stsc[L.ST_STOP] == L.STATUS_DIVERGED
    assert np.all(fr[:, IN_STATUS] == L.STATUS_DIVERGED)
    assert np.all(np.isfinite(fr)) and np.allclose(fr[:, IN_E_X], e0[IN_E_X], atol=1e-9)
    assert pa.stsc[L.ST_STOP_SEQ] == 1                      # the first sample


def test_reset_after_contact_starts_again_from_rest():
    d = ReynoldsPlantDriver(QUIET)
    d.impact("x", 1000.0, 1e-3)
    fr = d.run(np.full((20, 4), 5.0))
    assert fr[-1, IN_STATUS] == L.STATUS_CONTACT
    assert "contact" in d.status_text(int(fr[-1, IN_STATUS]))
    d.reset()
    c = d.counters()
    assert c["stopped"] == "" and c["substeps"] == 0 and c["stopped_at_seq"] is None
    fr = d.run(np.full((20, 4), 5.0))
    assert np.all(fr[:, IN_STATUS] == 0.0) and d.counters()["substeps"] == 80


def test_newton_bounds_are_validated():
    from rigd.errors import InputError

    with pytest.raises(InputError) as ei:
        ReynoldsPlantDriver({"newton_iterations": 4, "newton_max_iterations": 2})
    assert "newton_max_iterations" in str(ei.value)
