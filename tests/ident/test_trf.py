"""rigd.ident.trf: the trust-region reflective method on the QR factor of the Jacobian takes
scipy's steps (same iterates up to rounding, same evaluations, same stopping reason) on
bounded problems, with some bounds active at the solution and some not."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from rigd.ident.trf import least_squares_trf


def _decays(seed: int):
    """A tall, badly scaled problem: a sum of damped sines sampled at 4,000 points (three
    channels), fitted for their gains, rates and frequencies."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4, 4000)
    truth = np.array([1.0, 0.8, 6.0, 0.3, 0.2, 17.0, 0.05, 3.0, 40.0])

    def model(p):
        out = []
        for c in range(3):
            a, s, w = p[3 * c: 3 * c + 3]
            out.append(a * np.exp(-s * t) * np.sin(w * t))
        return np.concatenate(out)

    def jac(p):                                # the residual's analytic Jacobian
        J = np.zeros((3 * t.size, p.size))
        for c in range(3):
            a, s, w = p[3 * c: 3 * c + 3]
            e, rows = np.exp(-s * t), slice(c * t.size, (c + 1) * t.size)
            J[rows, 3 * c] = e * np.sin(w * t)
            J[rows, 3 * c + 1] = -t * a * e * np.sin(w * t)
            J[rows, 3 * c + 2] = t * a * e * np.cos(w * t)
        return J

    y = model(truth) + 0.01 * rng.standard_normal(3 * t.size)
    x0 = truth * (1 + 0.05 * rng.standard_normal(truth.size))
    return (lambda p: model(p) - y), x0, truth, jac


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("bounded", ["loose", "active"])
def test_same_steps_as_scipy(seed, bounded):
    fun, x0, truth, _ = _decays(seed)
    lo = np.full(x0.size, -np.inf)
    hi = np.full(x0.size, np.inf)
    lo[[1, 4]] = 0.0                           # rates ≥ 0: not active at the solution
    if bounded == "active":
        hi[2] = 5.5                            # the first frequency held below its truth
        lo[7] = 3.5                            # the last rate above its truth
    x0 = np.clip(x0, lo + 1e-3, hi - 1e-3)
    opts = dict(ftol=1e-10, xtol=1e-12, gtol=1e-12, x_scale="jac", diff_step=1e-7)
    ref = least_squares(fun, x0, bounds=(lo, hi), method="trf", **opts)
    got = least_squares_trf(fun, x0, bounds=(lo, hi), **opts)
    assert got.status == ref.status and got.success
    assert got.nfev == ref.nfev and got.njev == ref.njev
    np.testing.assert_allclose(got.x, ref.x, rtol=1e-7, atol=1e-9)
    assert got.cost == pytest.approx(ref.cost, rel=1e-9)
    np.testing.assert_array_equal(got.active_mask, ref.active_mask)
    if bounded == "loose":                     # it solved the problem
        np.testing.assert_allclose(got.x, truth, rtol=0.1, atol=0.01)
    else:
        assert got.active_mask[2] == 1 and got.active_mask[7] == -1
    # R (p × p) stands for the tall Jacobian: RᵀR = JᵀJ at the solution
    assert got.jac.shape == (x0.size, x0.size) and got.m == 3 * 4000
    np.testing.assert_allclose(got.jac.T @ got.jac, ref.jac.T @ ref.jac, rtol=1e-5,
                               atol=1e-6 * np.abs(ref.jac.T @ ref.jac).max())


def test_exact_jacobian_and_evaluation_cap():
    fun, x0, _, jac = _decays(3)
    bounds = (np.zeros(x0.size), np.full(x0.size, 100.0))
    for cap in (3, 50):
        ref = least_squares(fun, x0, jac=jac, bounds=bounds, method="trf", max_nfev=cap,
                            ftol=1e-10, xtol=1e-12, gtol=1e-12, x_scale="jac")
        got = least_squares_trf(fun, x0, jac=jac, bounds=bounds, max_nfev=cap,
                                ftol=1e-10, xtol=1e-12, gtol=1e-12)
        assert (got.status, got.nfev) == (ref.status, ref.nfev)
        np.testing.assert_allclose(got.x, ref.x, rtol=1e-7, atol=1e-9)
        # the cap of 3 evaluations stops it (status 0), 50 are enough to converge
        assert (got.status == 0) == (cap == 3) and got.nfev <= cap


def test_bad_start_is_refused():
    fun, x0, _, _ = _decays(0)
    with pytest.raises(ValueError, match="outside of provided bounds"):
        least_squares_trf(fun, x0, bounds=(x0 + 1, np.inf))
    with pytest.raises(ValueError, match="not finite"):
        least_squares_trf(lambda p: np.full(5, np.nan), x0, bounds=(-np.inf, np.inf))
