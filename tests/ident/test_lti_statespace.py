"""The general LTI family (rigd.ident.lti.statespace) and the readouts of any linear part.

Records are simulated with scipy.signal (not with rigd's own models): a 2-input 3-mode
structure, an integrator, a first-order lag with a delay.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sig

from rigd.ident.iddata import IdData
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.model import LinearPart, Model
from rigd.ident.pem import fit, fit_percent
from rigd.ident.readouts import linear_readouts, static_gain


def modal_record(fr, zeta, gains, fs=200.0, n=3000, noise=0.01, seed=1, offset=2.0):
    """y = Σ_k gains[k]·ω_k²/(s² + 2ζω_k s + ω_k²) u (2 inputs, 1 output), ZOH, + noise."""
    rng = np.random.default_rng(seed)
    nm = len(fr)
    A, B, C = np.zeros((2 * nm, 2 * nm)), np.zeros((2 * nm, 2)), np.zeros((1, 2 * nm))
    for k, (f, z, g) in enumerate(zip(fr, zeta, gains)):
        w = 2 * np.pi * f
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0, 1], [-w * w, -2 * z * w]]
        B[2 * k + 1] = np.asarray(g) * w * w
        C[0, 2 * k] = 1.0
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete((A, B, C, np.zeros((1, 2))), 1 / fs, "zoh")
    u = rng.standard_normal((n, 2))
    _, y, _ = sig.dlsim((Ad, Bd, Cd, Dd, 1 / fs), u)
    y = y + noise * np.std(y) * rng.standard_normal(y.shape) + offset
    return IdData(u, y, fs, ["u1", "u2"], ["y"])


def test_two_inputs_share_one_state_set_and_three_modes_are_found():
    d = modal_record([3.0, 11.0, 27.0], [0.05, 0.03, 0.08], [(1, 0.7), (2, -0.7), (3, 0.7)])
    est = d.slice(0, 2000)
    m = StateSpaceModel(["u1", "u2"], ["y"], d.fs, n_complex=3, hold="zoh")
    assert isinstance(m, Model) and m.nx == 6      # not 3 modes × 2 inputs
    m.set_record(est.n)
    res = fit(m, est, method="oe")
    got = sorted(md["f_n_hz"] for md in linear_readouts(m.linear_part(res.theta))["modes"])
    assert got == pytest.approx([3.0, 11.0, 27.0], rel=0.01)
    assert fit_percent(d.y[2000:], m.simulate(res.theta, d)[2000:])[0] > 95
    G0 = np.array(m.readouts(res.theta)["static_gain"])
    assert np.allclose(G0, [[6.0, 0.7]], rtol=0.03)


def test_static_gain_of_the_whole_model_is_its_own_step_response_end_value():
    d = modal_record([2.0, 9.0], [0.2, 0.1], [(1, -0.5), (0.5, 1.0)], n=2000)
    m = StateSpaceModel(["u1", "u2"], ["y"], d.fs, n_complex=2, n_real=1, hold="foh",
                        feedthrough=True)
    m.set_record(d.n)
    th = m.theta0(d)
    G0 = np.array(m.readouts(th)["static_gain"])
    th0 = th.copy()
    th0[m.x0_index + m.offset_index] = 0.0
    for j in range(2):
        u = np.zeros((6000, 2))
        u[:, j] = 1.0
        y = m.simulate(th0, IdData(u, np.zeros((6000, 1)), d.fs, ["u1", "u2"], ["y"]))
        assert y[-1, 0] == pytest.approx(G0[0, j], rel=1e-6, abs=1e-9)


def test_an_integrator_has_no_static_gain_but_an_integrating_gain():
    A = np.array([[0.0, 0.0], [0.0, -5.0]])
    B = np.array([[2.0], [1.0]])
    C = np.array([[1.0, 3.0]])
    lp = LinearPart(A, B, C, np.zeros((1, 1)), fs=100.0, integrators=(0,))
    G0, Gi = static_gain(lp)
    assert np.isinf(G0[0, 0]) and Gi[0, 0] == pytest.approx(2.0)
    ro = linear_readouts(lp)
    assert ro["integrators"] == 1 and ro["static_gain"] == [[None]]
    assert ro["modes"][0]["time_constant_s"] == pytest.approx(0.2)


def test_per_input_delays_shift_each_input():
    fs = 50.0
    rng = np.random.default_rng(3)
    u = rng.standard_normal((1500, 2))
    m = StateSpaceModel(["a", "b"], ["y"], fs, n_real=1, delays=[0, 3], hold="zoh")
    th = m.pack([complex(-2 * np.pi * 2.0, 0)], np.array([[1.0, 1.0]]), np.ones((1, 1)))
    y = m.simulate(th, IdData(u, np.zeros((1500, 1)), fs, ["a", "b"], ["y"]))
    u2 = u.copy()
    u2[3:, 1] = u[:-3, 1]
    u2[:3, 1] = u[0, 1]
    y2 = StateSpaceModel(["a", "b"], ["y"], fs, n_real=1, hold="zoh").simulate(
        th, IdData(u2, np.zeros((1500, 1)), fs, ["a", "b"], ["y"]))
    assert np.allclose(y, y2)


def test_spec_round_trip_and_pem_predictor():
    d = modal_record([4.0], [0.1], [(1, 0.5)], n=1500)
    m = StateSpaceModel(["u1", "u2"], ["y"], d.fs, n_complex=1, n_real=1, delays=[1, 0])
    again = StateSpaceModel.from_spec(m.spec())
    assert again.names == m.names and again.delays == (1, 0)
    res = fit(m, d.slice(0, 1000), method="pem")
    assert res.method == "pem" and np.all(np.isfinite(res.theta))
