"""The ``sim_reynolds`` driver in the loop: config, lock-step records, impacts, operating point."""

from pathlib import Path

import numpy as np
import pytest

from rigd.driver import driver_class
from rigd.errors import InputError
from rigd.loop.sim import simulate_record
from rigd_drivers.reynolds.driver import ReynoldsPlantDriver

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "config" / "sim_reynolds.yaml"


def test_registered_under_its_entry_point():
    assert driver_class("sim_reynolds") is ReynoldsPlantDriver


def test_bad_option_names_the_key():
    with pytest.raises(InputError) as ei:
        ReynoldsPlantDriver({"grid": {"n_z": 7}})
    assert "n_z" in str(ei.value) and "even" in str(ei.value)
    with pytest.raises(InputError) as ei:
        ReynoldsPlantDriver({"substepz": 3})
    assert "substepz" in str(ei.value)


def test_config_error_points_at_file_and_line(tmp_path):
    from rigd.loop.app import build_loop

    bad = tmp_path / "bad.yaml"
    bad.write_text(CONFIG.read_text().replace("substeps: 4 ", "substeps: 0 "))
    with pytest.raises(InputError) as ei:
        build_loop(bad, clock="lockstep")
    msg = str(ei.value)
    assert "bad.yaml:" in msg and "substeps" in msg


def test_lockstep_record_with_impact_and_prbs_in_the_loop():
    """The loop (PD valves, Eq. 1) runs the plant: valves follow r, the shaft answers u and the
    hammer; the impact rings at the plant's first mode."""
    rng = np.random.default_rng(3)
    n = 2500
    exc = np.repeat(rng.choice([-1.0, 1.0], size=(n // 50, 2)), 50, axis=0)   # 10 ms hold
    rec = simulate_record(CONFIG, exc, settle_s=0.05, post=1500,
                          events=[(n + 100, lambda p: p.impact("x", 20.0, 1e-3))])
    assert rec.meta["kind"] == "sim" and not rec.meta["faults"]
    ux = rec.columns["y_p2"] - rec.columns["y_p4"]
    ex = rec.columns["e_x"]
    # valves track the PRBS (κ_a ≈ 2), and e_x follows u_x (positive static gain)
    assert np.std(ux[:n]) > 1.0
    c = np.corrcoef(ux[:n], ex[:n])[0, 1]
    assert c > 0.4
    assert np.corrcoef(rec.columns["y_p1"] - rec.columns["y_p3"], rec.columns["e_y"])[0, 1] > 0.4
    # impact: peak force recorded, response rings down
    f = rec.columns["f_x"]
    assert f.max() == pytest.approx(20.0, rel=0.05)
    after = ex[n + 110:] - np.mean(ex[-300:])
    assert np.abs(after[:200]).max() > 5 * np.abs(after[-200:]).max()


def test_set_operating_point_changes_speed_and_pressure_frame():
    d = ReynoldsPlantDriver({"noise": {"e_um": 0.0, "y_p_v": 0.0}})
    d.set_operating_point(3000.0, 6.0)
    fr = d.run(np.full((10, 4), 5.0))
    assert fr[-1, 9] == 3000.0 and fr[-1, 10] == 6.0            # omega_rpm, p_inj_bar slots
    assert fr[-1, 6] > 0.0                                       # encoder angle moves
    with pytest.raises(InputError):
        d.set_operating_point(9000.0, 4.0)
