"""The one fit measure every figure of rigd is given in.

:func:`fit_percent` is what ``identify``, ``compare``, ``diagnose``, the order search, the
input-hold choice and the yardstick print: per output, 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) (%), as
MATLAB's ``compare`` (1 − NRMSE). 100 % is a perfect simulation, 0 % is no better than the
output's mean, below 0 % is worse than the mean.
"""

from __future__ import annotations

import numpy as np


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """Fit per output, 100·(1 − ‖y − ŷ‖/‖y − mean(y)‖) (%).

    Parameters
    ----------
    y, yhat : ndarray (n, ny) or (n,)
        Measured and simulated outputs (same units).

    Returns
    -------
    ndarray (ny,)
        Fit of each output, %; −inf for an output whose simulation diverged (a non-finite
        sample, or an error too large for its norm: an unstable candidate's free run), so a
        diverged model ranks last and raises no overflow warning.
    """
    y = np.atleast_2d(np.asarray(y, float).T).T
    yhat = np.atleast_2d(np.asarray(yhat, float).T).T
    with np.errstate(over="ignore", invalid="ignore"):
        num = np.linalg.norm(y - yhat, axis=0)
    den = np.linalg.norm(y - y.mean(axis=0), axis=0)
    fit = 100.0 * (1.0 - num / np.maximum(den, 1e-300))
    fit[~np.isfinite(num)] = -np.inf
    return fit


def mean_fit(y: np.ndarray, yhat: np.ndarray) -> float:
    """Mean over outputs of :func:`fit_percent` (%)."""
    return float(np.mean(fit_percent(y, yhat)))
