"""The compiled blocks: Eq. 1, K∞ state-space update, PD loop, clamp."""

from __future__ import annotations

import numpy as np
from loop_helpers import random_stable_controller
from numba import njit

from rigd.loop import cycle as K
from rigd.loop import layout as L


def test_eq1_mapping_exact():
    rng = np.random.default_rng(1)
    for rx, ry in rng.uniform(-4, 4, size=(200, 2)):
        assert K.eq1(5.0, rx, ry) == (5.0 + ry, 5.0 + rx, 5.0 - ry, 5.0 - rx)


def test_clamp_refuses_nan_and_limits():
    assert K.clamp(12.0, 0.0, 10.0) == 10.0
    assert K.clamp(-1.0, 0.0, 10.0) == 0.0
    assert K.clamp(3.5, 0.0, 10.0) == 3.5
    assert K.clamp(float("nan"), 0.0, 10.0) == 0.0


@njit
def _run_ss(prm, st, u, out):
    for k in range(u.shape[0]):
        a, b = K.ss_step(prm, st, u[k, 0], u[k, 1])
        out[k, 0] = a
        out[k, 1] = b


def _load(prm, st, ctrl):
    n = ctrl.order
    prm[L.P_KN] = n
    prm[L.P_KA:L.P_KA + n * n] = ctrl.A.ravel()
    prm[L.P_KB:L.P_KB + 2 * n] = ctrl.B.ravel()
    prm[L.P_KC:L.P_KC + 2 * n] = ctrl.C.ravel()
    prm[L.P_KD_MAT:L.P_KD_MAT + 4] = ctrl.D.ravel()


def test_kinf_update_matches_python_control():
    import control

    ctrl = random_stable_controller(4, seed=2)
    prm, st = np.zeros(L.N_PRM), np.zeros(L.N_ST)
    _load(prm, st, ctrl)
    u = np.random.default_rng(3).normal(size=(3000, 2))
    out = np.zeros_like(u)
    _run_ss(prm, st, u, out)
    sys = control.ss(ctrl.A, ctrl.B, ctrl.C, ctrl.D, 1 / 5000.0)
    ref = control.forced_response(sys, U=u.T).outputs.T
    assert np.max(np.abs(out - ref)) < 1e-9
    assert np.max(np.abs(ref)) > 1.0     # the comparison is not trivially on zeros


def test_zero_order_controller_is_static_gain_and_absent_is_zero():
    prm, st = np.zeros(L.N_PRM), np.zeros(L.N_ST)
    assert K.ss_step(prm, st, 3.0, -2.0) == (0.0, 0.0)   # no controller: zero output
    prm[L.P_KD_MAT:L.P_KD_MAT + 4] = [1.0, 2.0, 3.0, 4.0]
    assert K.ss_step(prm, st, 1.0, 1.0) == (3.0, 7.0)


@njit
def _pd(prm, st, refs, meas, out):
    for k in range(refs.shape[0]):
        out[k] = K.pd_step(prm, st, 0, refs[k], meas[k])


def test_pd_filtered_derivative_and_clamp():
    T, kp, kd, tf, kff = 2e-4, 1.5, 2e-4, 1e-4, 0.0
    prm, st = np.zeros(L.N_PRM), np.zeros(L.N_ST)
    prm[L.P_VMIN], prm[L.P_VMAX] = 0.0, 10.0
    prm[L.P_KP], prm[L.P_KD], prm[L.P_KFF] = kp, kd, kff
    prm[L.P_DA], prm[L.P_DB] = tf / (tf + T), 1 / (tf + T)
    st[L.S_EPREV] = np.nan
    rng = np.random.default_rng(4)
    refs = rng.uniform(2, 8, 500)
    meas = rng.uniform(2, 8, 500)
    out = np.zeros(500)
    _pd(prm, st, refs, meas, out)
    # reference implementation: d_k = (tf d_{k-1} + kd (e_k - e_{k-1})) / (tf + T)
    e = refs - meas
    d, ep, ref = 0.0, e[0], np.zeros(500)
    for k in range(500):
        d = (tf * d + kd * (e[k] - ep)) / (tf + T)
        ep = e[k]
        ref[k] = min(max(kff * refs[k] + kp * e[k] + d, 0.0), 10.0)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    assert out.max() == 10.0 and out.min() == 0.0     # the clamp was exercised
