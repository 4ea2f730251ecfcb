"""The linearised refit's share against the plain joint least-squares fit it replaces."""

import numpy as np
import pytest

from rigd.effects.linearised import factor, joint_share


def _direct(J, G, residual, y):
    """The joint fit written out: lstsq of the weighted residual on [G, J] and on J."""
    w = 1.0 / np.std(y, axis=0)
    re = (residual * w).reshape(-1)
    X = (np.concatenate([G, J], axis=-1) * w[None, :, None]).reshape(re.size, -1)
    k = G.shape[-1]
    sse = []
    for cols in (slice(0, None), slice(k, None)):
        b = np.linalg.lstsq(X[:, cols], re, rcond=None)[0]
        e = re - X[:, cols] @ b
        sse.append(e @ e)
        if cols.start == 0:
            beta = b[:k]
    return (sse[1] - sse[0]) / (re @ re), beta


@pytest.mark.parametrize("case", ["plain", "rank_deficient", "two_regressors"])
def test_projected_share_is_the_joint_fit(case):
    rng = np.random.default_rng(7)
    n, ny, q = 3000, 2, 6
    J = rng.standard_normal((n, ny, q)) * rng.uniform(0.01, 100, q)
    if case == "rank_deficient":
        J[..., -1] = 2.0 * J[..., 0]           # a sensitivity twice over
    k = 2 if case == "two_regressors" else 1
    G = rng.standard_normal((n, ny, k)) + 0.5 * J[..., 1:2]
    y = rng.standard_normal((n, ny)) * [1.0, 30.0]
    truth = J[..., 2] * 0.3 + G @ np.arange(1.0, k + 1)
    residual = truth + 0.5 * rng.standard_normal((n, ny))
    share, p, beta = joint_share(factor(J, residual, y), G)
    want, want_beta = _direct(J, G, residual, y)
    assert share == pytest.approx(want, rel=1e-9)
    np.testing.assert_allclose(beta, want_beta, rtol=1e-8)
    assert p < 1e-6


def test_a_regressor_inside_the_sensitivities_adds_nothing():
    rng = np.random.default_rng(3)
    n, ny, q = 2000, 1, 4
    J = rng.standard_normal((n, ny, q))
    G = (J[..., :2] @ [1.0, -2.0])[..., None]
    residual = rng.standard_normal((n, ny))
    share, p, beta = joint_share(factor(J, residual, residual + 1.0), G)
    assert share < 1e-12 and p > 0.5 and np.all(beta == 0.0)


def test_sensitivities_not_finite_give_no_basis():
    J = np.ones((10, 1, 2))
    J[3, 0, 1] = np.nan
    assert factor(J, np.ones((10, 1)), np.arange(10.0)[:, None]) is None
