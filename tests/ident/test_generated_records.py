"""The generated records of tests/gen carry the truth they claim: delays, orders and poles
recovered by the references of rigd.ident.lti; block-oriented curves, hysteresis and the
closed loop where they should be."""

import numpy as np
import pytest

from rigd.ident.lti import estimate_delays, fit_arx, heldout, n4sid
from tests.gen import joint, linear, nonlinear
from tests.gen.record import Generated


@pytest.mark.parametrize("delay", [0, 3, 6])
def test_thermal_delay_and_time_constant(delay):
    g = linear.thermal(delay=delay, seed=delay)
    assert g.u.shape == g.y.shape == (3000, 1) and g.fs == 1.0
    assert g.units == {"power": "%", "temperature": "degC"}
    (est,) = estimate_delays(g.u, g.y)
    assert abs(est.delay_zoh - delay) <= 0 and est.confidence >= 0.6
    m = fit_arx(g.u, g.y, 1, 1, delay + 1)
    pole = -m.a[0, 0, 0]
    assert abs(-1.0 / np.log(pole) - g.truth["time_constants"][0]) < 2.0   # s, fs = 1 Hz
    # a fractional delay lands between nk − 1 and nk
    (frac,) = estimate_delays(*_xy(linear.thermal(delay=2.5, seed=7)))
    assert frac.nk == 3


def _xy(g):
    return g.u, g.y


def test_structure_2in_6modes_poles():
    g = linear.structure_2in_6modes(seed=1)
    assert g.u.shape == (8000, 2) and g.y.shape == (8000, 2) and g.truth["order"] == 12
    r = n4sid(g.u[:6000], g.y[:6000], 12, fs=g.fs)
    want = np.exp(np.array(g.truth["poles"]) / g.fs)
    for p in want:
        assert np.min(np.abs(r.model.poles() - p)) < 0.01
    assert np.all(heldout(r.model, g.u, g.y, 6000)[0] > 90)


def test_structure_2in_3modes_and_its_delays():
    g = linear.structure_2in_3modes(seed=2, delays=[2, 0])
    assert g.u.shape == (6000, 2) and g.y.shape == (6000, 1)
    assert [f for f, _ in g.truth["modes"]] == [f for f, _ in linear.THREE_MODES]
    est = estimate_delays(g.u, g.y)
    assert abs(est[0].delay_zoh - 2) <= 1 and est[1].delay_zoh <= 1
    r = n4sid(g.u[:4000], g.y[:4000], 6, fs=g.fs)
    for p in np.exp(np.array(g.truth["poles"]) / g.fs):
        assert np.min(np.abs(r.model.poles() - p)) < 0.01


def test_integrator_loop_is_closed_loop_data():
    g = linear.integrator_loop(controller="PI", seed=3)
    r = g.truth["reference"]
    # y follows r (the loop works) and u is the controller's output of the measured error
    assert np.corrcoef(r, g.y[:, 0])[0, 1] > 0.9
    e = r - g.y[:, 0]
    kp, ti = g.truth["controller"]["kp"], g.truth["controller"]["ti_s"]
    u_pi = kp * (e + np.cumsum(e) / g.fs / ti)
    assert np.corrcoef(u_pi, g.u[:, 0])[0, 1] > 0.95
    # the plant integrates: an ARX model of u → y has a pole at 1
    m = fit_arx(g.u, g.y, 2, 2, 1)
    assert np.min(np.abs(np.roots(np.r_[1.0, m.a[:, 0, 0]]) - 1.0)) < 0.01
    p = linear.integrator_loop(controller="P", seed=3)
    assert np.corrcoef(p.truth["reference"], p.y[:, 0])[0, 1] > 0.9


@pytest.mark.parametrize("make, site", [(nonlinear.hammerstein, "input"),
                                        (nonlinear.wiener, "output")])
def test_block_oriented_records_are_not_linear(make, site):
    g = make(seed=4)
    assert g.truth["nonlinearity"]["site"] == site
    cut = 4000
    lin = n4sid(g.u[:cut], g.y[:cut], 2).model
    fit_lin = heldout(lin, g.u, g.y, cut)[0][0]
    # the same model with the true curve applied (input) or inverted (output) fits far better
    s = g.truth["nonlinearity"]["scale"]
    if site == "input":
        v = s * nonlinear.CURVES[g.truth["nonlinearity"]["curve"]](g.u / s)
        m = n4sid(v[:cut], g.y[:cut], 2).model
        fit_true = heldout(m, v, g.y, cut)[0][0]
    else:
        x = s * np.arctanh(np.clip(1.5 * g.y_clean / s, -0.999999, 0.999999)) / 1.5
        m = n4sid(g.u[:cut], x[:cut], 2).model
        fit_true = heldout(m, g.u, x, cut)[0][0]
    assert fit_true > 97 and fit_true > fit_lin + 3


def test_bouc_wen_has_hysteresis():
    g = nonlinear.bouc_wen(n=4000, seed=5)
    weak = nonlinear.bouc_wen(n=4000, seed=5, beta=1e-3)   # almost linear restoring force
    cut = 3000
    fits = []
    for rec in (g, weak):
        m = n4sid(rec.u[:cut], rec.y[:cut], 2).model
        fits.append(heldout(m, rec.u, rec.y, cut)[0][0])
    assert fits[1] > 97 and fits[0] < fits[1] - 2


def _steady(g: Generated, n: int) -> Generated:
    """The last multisine period of ``g`` (the first is the transient)."""
    return Generated(g.u[-n:], g.y[-n:], g.fs, g.inputs, g.outputs, g.units, g.truth)


def test_joint_structure_mode_softens_and_damps_with_force_level():
    """The Iwan joint: stuck at the low level (the mode at its stuck frequency and damping),
    softer and more damped at each higher level; the other modes do not move."""
    n = 8192
    recs = [_steady(joint.joint_structure(level=lv, periods=2, n=n, n_outputs=1), n)
            for lv in (1.0, 3.0, 10.0)]
    f_st, z_st = recs[0].truth["modes_stuck"][0]
    (f1, z1), (f3, z3), (f10, z10) = (joint.mode_near(r, f_st) for r in recs)
    assert abs(f1 / f_st - 1) < 0.005 and abs(z1 / z_st - 1) < 0.3
    assert f10 < f3 < f1 and f10 < 0.985 * f1
    assert z10 > z3 > 1.5 * z1
    f2 = recs[0].truth["modes"][1][0]
    lo, hi = joint.mode_near(recs[0], f2)[0], joint.mode_near(recs[2], f2)[0]
    assert abs(hi / lo - 1) < 0.003


def test_joint_structure_clearance_stiffens():
    n = 8192
    f = [joint.mode_near(_steady(joint.joint_structure(level=lv, joint="clearance",
                                                       periods=2, n=n, n_outputs=1), n), 7.4)[0]
         for lv in (0.3, 10.0)]
    assert abs(f[0] / 7.0 - 1) < 0.01 and f[1] > 1.06 * f[0]


def test_writers(tmp_path):
    g = linear.thermal(n=200)
    head, data = g.columns()
    back = np.loadtxt(g.write_csv(tmp_path / "t.csv"), delimiter=",", skiprows=1)
    assert head == ["t", "power", "temperature"] and np.array_equal(back, data)
    import h5py
    import scipy.io

    assert np.array_equal(scipy.io.loadmat(g.write_mat(tmp_path / "a.mat"))["data"], data)
    with h5py.File(g.write_mat(tmp_path / "b.mat", v73=True)) as f:
        assert np.array_equal(f["data"][()].T, data)
    assert (tmp_path / "b.mat").read_bytes()[:10] == b"MATLAB 7.3"
