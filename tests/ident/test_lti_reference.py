"""Black-box reference estimators (rigd.ident.lti): ARX, subspace, per-input delays and the
held-out protocol, on systems simulated with scipy.signal (not rigd's models)."""

import numpy as np
import pytest
from scipy import signal

from rigd.ident.lti import estimate_delays, fit_arx, heldout, n4sid, select_arx, select_subspace
from rigd.ident.lti.lsq import stacked_r


def _modes_tf(modes, fs, gain=1.0):
    """Discrete (ZOH) transfer function of parallel-free cascaded modes [(f Hz, ζ)]."""
    num, den = np.array([gain]), np.array([1.0])
    for f, z in modes:
        w = 2 * np.pi * f
        num = np.polymul(num, [w * w])
        den = np.polymul(den, [1, 2 * z * w, w * w])
    b, a, _ = signal.cont2discrete((num, den), 1 / fs, "zoh")
    return b.ravel(), a


def _match(got, want):
    """Largest distance between two sets of poles matched greedily."""
    got, worst = list(got), 0.0
    for p in want:
        k = int(np.argmin([abs(p - g) for g in got]))
        worst = max(worst, abs(p - got.pop(k)))
    return worst


def test_stacked_r_is_the_qr_of_the_whole_matrix():
    M = np.random.default_rng(1).standard_normal((1000, 7))
    R = stacked_r(lambda a, b: M[a:b], len(M), 7, chunk=64)
    assert np.allclose(R.T @ R, M.T @ M)


@pytest.mark.parametrize("modes", [[(3.0, 0.05)], [(2.0, 0.05), (9.0, 0.02)],
                                   [(1.5, 0.1), (6.0, 0.03), (17.0, 0.02)]])
def test_subspace_recovers_the_poles_at_several_orders(modes):
    fs = 100.0
    b, a = _modes_tf(modes, fs)
    rng = np.random.default_rng(2)
    u = rng.standard_normal(8000)
    y = signal.lfilter(b, a, u)
    y += 0.01 * y.std() * rng.standard_normal(len(y))
    r = n4sid(u, y, 2 * len(modes), fs=fs)
    assert r.order == 2 * len(modes)
    assert _match(r.model.poles(), np.roots(a)) < 2e-3
    # the order read from the singular values is the true one
    assert n4sid(u, y, fs=fs).order == 2 * len(modes)
    fit, _ = heldout(r.model, u, y, 6000)
    assert fit[0] > 97.0


def test_subspace_mimo_2x2_and_its_gains():
    rng = np.random.default_rng(3)
    A = np.array([[0.9, 0.2, 0, 0], [-0.2, 0.9, 0, 0], [0, 0, 0.7, 0], [0, 0, 0, 0.95]])
    B = rng.standard_normal((4, 2))
    C = rng.standard_normal((2, 4))
    D = np.array([[0.3, 0.0], [0.0, -0.2]])
    n = 6000
    u = rng.standard_normal((n, 2)) + np.array([1.0, -2.0])
    _, y, _ = signal.dlsim((A, B, C, D, 1.0), u)
    y += 0.01 * y.std(0) * rng.standard_normal(y.shape) + np.array([5.0, 7.0])
    r = n4sid(u, y, 4)
    assert _match(r.model.poles(), np.linalg.eigvals(A)) < 5e-3
    assert np.allclose(r.model.D, D, atol=0.02)
    true_dc = C @ np.linalg.solve(np.eye(4) - A, B) + D
    assert np.allclose(r.model.dc_gain(), true_dc, rtol=0.02, atol=0.02)
    fit, yhat = heldout(r.model, u, y, 4000)
    assert yhat.shape == (2000, 2) and np.all(fit > 97.0)
    # the order read from the singular values: 4, or one more where a slow pole (0.95) outlives
    # the past window (finite-horizon bias), and then no better on held-out data
    auto = n4sid(u, y)
    assert auto.order in (4, 5)
    assert np.all(heldout(auto.model, u, y, 4000)[0] < fit + 0.5)
    # the held-out figure does not look at the validation outputs
    y2 = y.copy()
    y2[4000:] = 0.0
    _, yhat2 = heldout(r.model, u, y2, 4000)
    assert np.array_equal(yhat, yhat2)


def test_subspace_kalman_gain_predicts_better_than_free_run():
    """Output noise coloured by the plant's own dynamics (innovation form): the one-step
    predictor with K beats the free run."""
    rng = np.random.default_rng(4)
    A = np.array([[0.95, 0.1], [-0.1, 0.95]])
    B, C, K = np.array([[1.0], [0.0]]), np.array([[1.0, 0.5]]), np.array([[0.5], [0.3]])
    n = 5000
    u, e = rng.standard_normal(n), 0.5 * rng.standard_normal(n)
    x, y = np.zeros(2), np.empty(n)
    for k in range(n):
        y[k] = C[0] @ x + e[k]
        x = A @ x + B[:, 0] * u[k] + K[:, 0] * e[k]
    m = n4sid(u, y, 2).model
    pred_err = np.std(y - m.predict(u, y)[:, 0])
    sim_err = np.std(y - m.simulate(u)[:, 0])
    assert pred_err < 0.6 and pred_err < 0.7 * sim_err


def test_arx_recovers_the_coefficients_of_an_arx_system():
    rng = np.random.default_rng(5)
    n = 5000
    u = rng.standard_normal((n, 2))
    e = 0.05 * rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(4, n):   # y + a1 y1 + a2 y2 = 0.5 u1[t-1] + 0.2 u1[t-2] - 0.7 u2[t-3] + e
        y[t] = (1.2 * y[t - 1] - 0.5 * y[t - 2] + 0.5 * u[t - 1, 0] + 0.2 * u[t - 2, 0]
                - 0.7 * u[t - 3, 1] + e[t])
    m = fit_arx(u, y + 3.0, na=2, nb=[2, 1], nk=[1, 3])
    assert np.allclose(m.a[:, 0, 0], [-1.2, 0.5], atol=0.01)
    assert np.allclose(m.b[1:3, 0, 0], [0.5, 0.2], atol=0.01)
    assert np.allclose(m.b[3, 0, 1], -0.7, atol=0.01) and m.b[1, 0, 1] == 0.0
    # the linear (observer) form predicts exactly like the ARX equation
    lin = m.to_linear()
    p = lin.predict(u, y + 3.0)[:, 0]
    t = np.arange(4, n)
    ref = (m.y0[0] - m.a[0, 0, 0] * (y[t - 1] + 3 - m.y0[0]) - m.a[1, 0, 0] * (y[t - 2] + 3 -
           m.y0[0]) + m.b[1, 0, 0] * (u[t - 1, 0] - m.u0[0]) + m.b[2, 0, 0] *
           (u[t - 2, 0] - m.u0[0]) + m.b[3, 0, 1] * (u[t - 3, 1] - m.u0[1]))
    assert np.allclose(p[t], ref, atol=1e-9)
    sel = select_arx(u, y, orders=(1, 2, 3, 4))
    assert sel.nk == (1, 3) and sel.order >= 2


def test_arx_refuses_a_record_too_short():
    with pytest.raises(ValueError, match="too short"):
        fit_arx(np.zeros(20), np.zeros(20), 5, 5, 1)


@pytest.mark.parametrize("delays", [(0, 4), (2, 7), (5, 1)])
def test_delays_of_first_order_plants_behind_a_zero_order_hold(delays):
    """Two inputs through first-order lags (τ = 20 and 8 samples) with transport delays of
    whole samples: the ZOH lag is delay + 1, delay_zoh the delay itself."""
    rng = np.random.default_rng(sum(delays))
    n = 4000
    u = np.repeat(rng.standard_normal((n // 10, 2)), 10, axis=0)   # steps held 10 samples
    y = np.zeros(n)
    for j, (tau, d, g) in enumerate([(20.0, delays[0], 2.0), (8.0, delays[1], -1.0)]):
        b, a, _ = signal.cont2discrete(([g], [tau, 1.0]), 1.0, "zoh")
        y += signal.lfilter(b.ravel(), a, np.concatenate([np.zeros(d), u[:n - d, j]]))
    y += 0.02 * y.std() * rng.standard_normal(n)
    est = estimate_delays(u, y)
    assert [e.delay_zoh for e in est] == list(delays)
    assert [e.nk for e in est] == [d + 1 for d in delays]
    assert all(e.confidence >= 0.6 for e in est)


def test_delay_of_an_input_that_does_nothing_has_no_confidence():
    rng = np.random.default_rng(9)
    u = rng.standard_normal((3000, 2))
    y = signal.lfilter([0, 0, 0.5], [1, -0.8], u[:, 0]) + 0.1 * rng.standard_normal(3000)
    est = estimate_delays(u, y)
    assert est[0].nk == 2 and est[0].confidence == 1.0
    assert est[1].confidence <= 0.4


def test_select_subspace_uses_the_estimation_data_only():
    fs = 50.0
    b, a = _modes_tf([(2.0, 0.05), (7.0, 0.03)], fs)
    rng = np.random.default_rng(6)
    u = rng.standard_normal(6000)
    y = signal.lfilter(b, a, u) + 0.05 * rng.standard_normal(6000)
    res, scores = select_subspace(u[:4000], y[:4000], orders=(2, 4, 6, 8), fs=fs)
    assert res.order in (4, 5, 6) and scores[4] > scores[2] + 10
    fit, _ = heldout(res.model, u, y, 4000)
    assert fit[0] > 90


def test_select_subspace_keeps_a_stable_refit(monkeypatch):
    """The order is chosen on a split of the estimation data and refitted on all of it; a
    refit that comes out unstable is not returned (the next best stable one is)."""
    from rigd.ident.lti import subspace

    fs = 50.0
    b, a = _modes_tf([(2.0, 0.05), (7.0, 0.03)], fs)
    rng = np.random.default_rng(4)
    u = rng.standard_normal(4000)
    y = signal.lfilter(b, a, u) + 0.05 * rng.standard_normal(4000)
    _, scores = select_subspace(u, y, orders=(2, 4, 6, 8), fs=fs)
    first = max(scores, key=lambda k: (scores[k], -k))
    real = subspace._Decomposition.model

    def unstable_refit(self, nx, refine=True, stabilise=False):
        m = real(self, nx, refine, stabilise)
        if self.j > 3000 and nx == first and not stabilise:   # the refit on all 4000
            m.A = 1.5 * m.A
        return m

    monkeypatch.setattr(subspace._Decomposition, "model", unstable_refit)
    res, _ = select_subspace(u, y, orders=(2, 4, 6, 8), fs=fs)
    assert res.model.stable() and res.order != first


def test_arx_yardstick_delay_on_a_chain_of_high_relative_degree():
    """Three cascaded modes (relative degree 6, no transport delay): the first significant
    lag of the impulse response comes many samples late, but the ARX delay is chosen with
    the order by the check fit, and the model reaches what a subspace model does."""
    fs = 200.0
    b, a = _modes_tf([(3.0, 0.03), (8.0, 0.02), (13.0, 0.02)], fs)
    rng = np.random.default_rng(11)
    u = rng.standard_normal(6000)
    y = signal.lfilter(b, a, u)
    y = y + 0.01 * y.std() * rng.standard_normal(6000)
    naive = estimate_delays(u[:4000], y[:4000])[0].nk
    sel = select_arx(u[:4000], y[:4000], orders=(4, 8, 15, 30), fs=fs)
    arx_fit, _ = heldout(sel.model.to_linear(), u, y, 4000)
    sub, _ = select_subspace(u[:4000], y[:4000], orders=(4, 6, 8), fs=fs)
    sub_fit, _ = heldout(sub.model, u, y, 4000)
    assert naive > 3 and sel.nk[0] < naive, (sel.nk, naive)
    assert arx_fit[0] > sub_fit[0] - 1, (arx_fit, sub_fit)
