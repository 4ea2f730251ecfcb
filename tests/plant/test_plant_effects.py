"""Hidden effects: each, switched on, leaves its physical signature; off, none is there."""

import control
import numpy as np
import pytest

from rigd.frame import IN_E_X, IN_E_Y, IN_PHI, IN_YP1, N_IN
from rigd_drivers.plant import physics as phys
from rigd_drivers.sim.driver import SimPlantDriver

QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}


def _prbs_drive(n, seed=0, hold=5):
    rng = np.random.default_rng(seed)
    lv = rng.choice([-1.0, 1.0], size=(n // hold + 1, 2))
    r = np.repeat(lv, hold, axis=0)[:n]
    return np.column_stack([5 + r[:, 1], 5 + r[:, 0], 5 - r[:, 1], 5 - r[:, 0]])


def _record(effects, drives, **opts):
    d = SimPlantDriver({"effects": effects, **opts})
    f0 = np.zeros(N_IN)
    d.read(f0)
    return np.vstack([f0, d.run(drives)])


def _model_residual(frames, omega=0.0, p=4.0):
    """Measured e minus the TRUE linear bearing model (Eq. 5) driven by the measured u."""
    y = frames[:, IN_YP1:IN_YP1 + 4]
    u = np.column_stack([y[:, 1] - y[:, 3], y[:, 0] - y[:, 2]])
    e = frames[:, [IN_E_X, IN_E_Y]]
    t = np.arange(len(u)) / 5000.0
    x0 = np.concatenate([e[0], [0.0, 0.0]])
    model = control.forced_response(phys.bearing_ss(omega, p), T=t, U=u.T, X0=x0).outputs.T
    return e - model, model


@pytest.mark.parametrize("samples", [0, 3, 7])
def test_delay_shifts_cross_correlation_peak(samples):
    eff = {"delay": {"enabled": True, "samples": samples}} if samples else {}
    frames = _record(eff, _prbs_drive(4000))                  # default sensor noise
    _, model = _model_residual(frames)
    e = frames[:, IN_E_X] - frames[:, IN_E_X].mean()
    m = model[:, 0] - model[:, 0].mean()
    lags = np.arange(-10, 11)
    xc = [np.dot(e[20 + lag:-20 + lag], m[20:-20]) for lag in lags]
    assert lags[int(np.argmax(xc))] == samples


def test_delay_is_a_pure_shift_of_the_bearing_input():
    drives = _prbs_drive(3000)
    off = _record({}, drives, **QUIET)
    on = _record({"delay": {"enabled": True, "samples": 4}}, drives, **QUIET)
    assert np.array_equal(on[:, IN_YP1:IN_YP1 + 4], off[:, IN_YP1:IN_YP1 + 4])  # valves same
    e_on, e_off = on[:, IN_E_X], off[:, IN_E_X]
    assert np.allclose(e_on[4:], e_off[:-4], rtol=0, atol=1e-9 * np.abs(e_off).max())


def _impact_response(effects, peak):
    d = SimPlantDriver({"effects": effects, **QUIET})
    drive = np.full((600, 4), 5.0)
    base = d.run(drive[:20])[-1, IN_E_X]
    d.impact("x", peak, 1e-3)
    return (d.run(drive)[:, IN_E_X] - base) / peak


def _zero_crossing_freq(x):
    s = np.signbit(x[8:300])
    idx = np.nonzero(s[1:] != s[:-1])[0]
    return 5000.0 / (2 * np.mean(np.diff(idx)))


def test_cubic_stiffness_makes_response_amplitude_dependent():
    small_off, big_off = _impact_response({}, 2.0), _impact_response({}, 60.0)
    assert np.allclose(small_off, big_off, rtol=0, atol=1e-9)      # linear: scales exactly
    eff = {"cubic_stiffness": {"enabled": True}}
    small, big = _impact_response(eff, 2.0), _impact_response(eff, 60.0)
    assert np.abs(big * 60).max() > 10.0                           # large eccentricity reached
    assert np.abs(small - small_off).max() < 0.01 * np.abs(small_off).max()
    assert np.abs(big - small).max() > 0.1 * np.abs(small).max()
    assert _zero_crossing_freq(big) > 1.03 * _zero_crossing_freq(small)   # film stiffens


def _harmonics(x, phi):
    A = np.column_stack([np.ones_like(phi), np.cos(phi), np.sin(phi),
                         np.cos(2 * phi), np.sin(2 * phi)])
    c, *_ = np.linalg.lstsq(A, x, rcond=None)
    return c[1] + 1j * c[2], c[3] + 1j * c[4]     # phasors: a·cos(kφ) + b·sin(kφ) -> a + jb


def test_runout_and_unbalance_locked_to_shaft_angle():
    omega = 3000.0
    drives = np.full((10000, 4), 5.0)
    on = _record({"runout": {"enabled": True}}, drives, omega_rpm=omega)[2500:]
    off = _record({}, drives, omega_rpm=omega)[2500:]
    ro = SimPlantDriver({}).opts.effects.runout
    phi = on[:, IN_PHI]
    # expected 1×: surface run-out + steady unbalance response H_f(jΩ)·F
    w = omega * 2 * np.pi / 60
    F = ro.unbalance_g_mm * 1e-6 * w ** 2
    H = phys.bearing_ss(omega, 4.0, force_inputs=True)(1j * w)[:, 2:]   # (2, 2) µm/N
    f_ph = F * np.exp(1j * np.deg2rad(ro.unbalance_phase_deg)) * np.array([1.0, -1j])
    unb = H @ f_ph                                   # complex amplitude in e^{jφ} convention
    for ch, amps, phs, u_c in ((IN_E_X, ro.x_um, ro.x_phase_deg, unb[0]),
                               (IN_E_Y, ro.y_um, ro.y_phase_deg, unb[1])):
        h1, h2 = _harmonics(on[:, ch], phi)
        exp2 = amps[1] * np.exp(-1j * np.deg2rad(phs[1]))            # a cos(2φ+θ)
        exp1 = amps[0] * np.exp(-1j * np.deg2rad(phs[0])) + np.conj(u_c)
        assert abs(h2 - exp2) < 0.05 * abs(exp2), (h2, exp2)
        assert abs(h1 - exp1) < 0.05 * abs(exp1), (h1, exp1)
        g1, g2 = _harmonics(off[:, ch], off[:, IN_PHI])
        assert abs(g1) < 0.005 and abs(g2) < 0.005                  # only noise when off
    assert abs(unb[0]) > 0.1                                          # unbalance matters


def test_extra_mode_adds_a_narrow_peak_the_model_lacks():
    drives = _prbs_drive(8000, hold=1)
    off, _ = _model_residual(_record({}, drives, **QUIET))
    frames = _record({"extra_mode": {"enabled": True}}, drives, **QUIET)
    res, model = _model_residual(frames)
    assert np.abs(off).max() < 1e-6 * np.abs(model).max()
    assert res[:, 0].std() > 0.05 * (model[:, 0] - model[:, 0].mean()).std()
    from scipy.signal import csd, welch
    y = frames[:, IN_YP1:IN_YP1 + 4]
    ux = y[:, 1] - y[:, 3]
    f, puu = welch(ux, fs=5000.0, nperseg=2048)
    _, pur = csd(ux, res[:, 0], fs=5000.0, nperseg=2048)
    frf = np.abs(pur / puu)                      # u_x -> residual: the missing dynamics
    assert abs(f[np.argmax(frf)] - 240.0) < 5.0
    band = (f > 200) & (f < 280)
    assert frf[band].max() > 10 * np.median(frf[(f > 20) & (f < 1000)])    # narrow


def _triangle(n_ramp, lo=2.0, hi=8.0):
    up = np.linspace(lo, hi, n_ramp)
    v = np.concatenate([np.full(500, lo), up, up[::-1], np.full(500, lo)])
    return np.repeat(v[:, None], 4, axis=1)


def test_hysteresis_makes_valve_position_depend_on_direction():
    drives = _triangle(5000)
    v = drives[:, 0]
    for eff, lo, hi in (({}, -0.03, 0.03), ({"hysteresis": {"enabled": True}}, 0.6, 1.1)):
        y = _record(eff, drives, **QUIET)[1:, IN_YP1]
        i_up = 500 + np.argmin(np.abs(v[500:5500] - 5.0))
        i_dn = 5500 + np.argmin(np.abs(v[5500:10500] - 5.0))
        gap = y[i_dn] - y[i_up]                  # descending branch above ascending branch
        assert lo < gap < hi, (eff, gap)


def test_creep_drifts_slowly_after_a_step():
    drives = np.full((8000, 4), 3.0)
    drives[500:] = 6.0
    for eff in ({}, {"creep": {"enabled": True}}):
        y = _record(eff, drives, **QUIET)[1:, IN_YP1]
        early, late = y[500 + 75], y[-1]        # 15 ms and 1.5 s after the step
        if eff:
            assert late - early > 0.15           # ≥ 5 % of the 3 V step
            assert np.all(np.diff(y[575:]) >= -1e-12)   # monotone creep, no oscillation
        else:
            assert abs(late - early) < 1e-3


def test_hysteresis_sees_the_clamped_drive():
    """Drive beyond the amplifier range is clamped before the piezo: pushing further past
    10 V changes nothing, with or without hysteresis."""
    for eff in ({}, {"hysteresis": {"enabled": True}}):
        a = np.vstack([np.full((200, 4), 10.0), np.full((400, 4), 4.0)])
        b = np.vstack([np.full((100, 4), 10.0), np.full((100, 4), 25.0), np.full((400, 4), 4.0)])
        ya = _record(eff, a, **QUIET)[:, IN_YP1]
        yb = _record(eff, b, **QUIET)[:, IN_YP1]
        assert np.array_equal(ya, yb)
