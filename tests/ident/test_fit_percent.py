"""rigd.ident.figures.fit_percent on diverged simulations: ranked last, no overflow warning
(the demo's yardstick ARX scan met an unstable candidate whose free run overflowed)."""

import warnings

import numpy as np

from rigd.ident.figures import fit_percent, mean_fit


def test_diverged_output_fits_minus_infinity_without_a_warning():
    t = np.linspace(0, 1, 500)
    y = np.column_stack([np.sin(7 * t), np.cos(3 * t)])
    yhat = y.copy()
    yhat[:, 0] = np.exp(np.linspace(0, 800, 500))      # overflows the norm (1e347)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = fit_percent(y, yhat)
        yhat[10, 1] = np.nan
        fit_nan = fit_percent(y, yhat)
    assert fit[0] == -np.inf and abs(fit[1] - 100.0) < 1e-9
    assert fit_nan[1] == -np.inf
    assert mean_fit(y, yhat) == -np.inf


def test_ordinary_fit_unchanged():
    rng = np.random.default_rng(0)
    y = rng.standard_normal((400, 1))
    y -= y.mean()
    assert abs(fit_percent(y, y + 0.1 * y)[0] - 90.0) < 1e-9
    assert abs(fit_percent(y, np.full_like(y, y.mean()))[0]) < 1e-9
