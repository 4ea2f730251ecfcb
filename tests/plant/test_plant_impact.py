"""Impact hammer on the plant alone (valves held by a constant drive): modes come back."""

import numpy as np
import pytest

from rigd.frame import IN_E_X, IN_E_Y, IN_F_X, IN_F_Y
from rigd_drivers.plant import physics as phys
from rigd_drivers.sim.driver import SimPlantDriver


def _impact_record(omega, p, axis, opts=None, peak=20.0, dur=1e-3, n=1500):
    d = SimPlantDriver({"omega_rpm": omega, "p_inj_bar": p, **(opts or {})})
    drive = np.full((n, 4), d.opts.valves.initial_drive_v)
    base = d.run(drive[:50])[:, [IN_E_X, IN_E_Y]].mean(axis=0)
    d.impact(axis, peak, dur)
    frames = d.run(drive)
    frames[:, [IN_E_X, IN_E_Y]] -= base                # equilibrium removed
    return frames


@pytest.mark.parametrize("omega, p", [(0.0, 4.0), (0.0, 7.0), (6000.0, 5.0)])
def test_impact_gives_back_configured_modes(omega, p, free_modes):
    frames = _impact_record(omega, p, "x")            # default sensor noise on
    free = frames[10:, [IN_E_X, IN_E_Y]]              # after the 1 ms pulse
    f_est, z_est = free_modes([free])
    f_true, z_true = phys.bearing_modes(omega, p)
    assert np.allclose(f_est, f_true, rtol=0.05), (f_est, f_true)
    assert np.allclose(z_est, z_true, rtol=0.05), (z_est, z_true)
    if omega == 0.0:
        paper = {4.0: 0.057, 7.0: 0.028}[p]
        assert np.allclose(z_est, paper, rtol=0.08)


def test_log_decrement_of_horizontal_impact_at_4bar():
    """Classical estimate on e_x alone: peaks of the free response decay as exp(−ζωt)."""
    frames = _impact_record(0.0, 4.0, "x", {"noise": {"e_um": 0.0, "y_p_v": 0.0}}, n=800)
    ex = frames[10:, IN_E_X]
    pk = [i for i in range(1, len(ex) - 1) if ex[i] > ex[i - 1] and ex[i] >= ex[i + 1]]
    n_per = np.diff(pk).mean()
    f_est = 5000.0 / n_per
    delta = np.log(ex[pk[0]] / ex[pk[4]]) / 4
    z_est = delta / np.sqrt(4 * np.pi ** 2 + delta ** 2)
    f_true, z_true = phys.bearing_modes(0.0, 4.0)
    assert f_est == pytest.approx(f_true[0], rel=0.05)
    assert z_est == pytest.approx(z_true[0], rel=0.10)  # y-mode leakage beats a little


def test_hammer_force_is_recorded_half_sine():
    frames = _impact_record(0.0, 4.0, "y", peak=30.0, dur=2e-3, n=40)
    fy = frames[:, IN_F_Y]
    assert np.all(frames[:, IN_F_X] == 0.0)
    t = np.arange(1, 41) / 5000.0
    expect = np.where(t < 2e-3, 30.0 * np.sin(np.pi * t / 2e-3), 0.0)
    assert np.allclose(fy, expect, atol=1e-12)
    assert abs(frames[20:, IN_E_Y]).max() > 1.0   # it moved the shaft


def test_bad_impact_refused():
    from rigd.errors import InputError
    d = SimPlantDriver({})
    for args in (("z", 10, 1e-3), ("x", float("nan"), 1e-3), ("x", 10, 0.0), ("x", 5e3, 1e-3)):
        with pytest.raises(InputError):
            d.impact(*args)
