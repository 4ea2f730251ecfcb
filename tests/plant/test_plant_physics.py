"""True parameters vs operating point (rigd_drivers.plant.physics)."""

import control
import numpy as np
import pytest

from rigd_drivers.plant import physics as phys


def test_modes_inside_band_over_the_whole_range():
    for om in np.linspace(0, 6000, 7):
        for p in np.linspace(3, 7, 9):
            f, z = phys.bearing_modes(om, p)
            assert f.shape == (2,)
            assert np.all((f > 70) & (f < 190)), (om, p, f)
            assert np.all(z > 0.01), (om, p, z)


@pytest.mark.parametrize("p, zeta", [(4.0, 0.057), (7.0, 0.028)])
def test_damping_matches_paper_at_standstill(p, zeta):
    _, z = phys.bearing_modes(0.0, p)
    assert np.allclose(z, zeta, rtol=0.04)


def test_pressure_stiffens_and_speed_splits_modes():
    f3, _ = phys.bearing_modes(0, 3)
    f7, _ = phys.bearing_modes(0, 7)
    assert np.all(f7 > 1.3 * f3)
    gaps = [np.diff(phys.bearing_modes(om, 5)[0])[0] for om in (0, 3000, 6000)]
    assert gaps[0] < gaps[1] < gaps[2]          # gyroscopic splitting grows with Ω
    zs = [phys.bearing_modes(om, 5)[1][0] for om in (0, 6000)]
    assert zs[1] < zs[0]                        # circulatory film force lowers damping


def test_identified_form_of_eq6():
    bm = phys.bearing_matrices(4000, 7)
    Minv = np.linalg.inv(bm.M)
    assert np.allclose(bm.D_id, Minv @ (bm.D - bm.omega_rad_s * bm.G))
    assert np.allclose(bm.K_id, Minv @ bm.K)
    assert np.allclose(bm.B_id, Minv @ bm.B_p)
    assert np.allclose(bm.G, -bm.G.T) and bm.G[0, 1] != 0
    assert bm.K[0, 1] != bm.K[1, 0]            # circulatory cross-coupling at speed
    sys = phys.bearing_ss(4000, 7)
    dc = sys.dcgain()
    assert 0.5 < dc[0, 0] < 1.5 and 0.5 < dc[1, 1] < 1.5          # µm per V of u
    assert 0 < abs(dc[0, 1]) < 0.3 * dc[0, 0]


def test_out_of_range_refused():
    with pytest.raises(ValueError, match="p_inj_bar"):
        phys.bearing_matrices(0, 8)
    with pytest.raises(ValueError, match="omega_rpm"):
        phys.bearing_modes(-1, 4)


def test_valve_closed_loop_with_suggested_pd():
    for v in phys.valve_params():
        m = phys.step_metrics(phys.valve_closed_loop(v))
        assert m["overshoot"] < 0.02
        assert m["settling_s"] <= 2e-3
        assert 400 <= m["bandwidth_hz"] <= 800
        alone = phys.step_metrics(control.c2d(phys.valve_tf(v), 2e-4))
        assert alone["bandwidth_hz"] < 250         # the PD loop matters
    for axis in ("x", "y"):
        m = phys.step_metrics(phys.lumped_actuator_tf(axis))
        assert 1.9 < m["static_gain"] < 2.1 and 400 <= m["bandwidth_hz"] <= 800
    m = phys.step_metrics(phys.lumped_actuator_tf("x", kff=0.0, kd=2e-4))   # without feed-forward
    assert 1.1 < m["static_gain"] < 1.3 and m["overshoot"] < 0.02
