"""The one fit measure every figure of rigd is given in.

:func:`fit_percent` is what ``identify``, ``compare``, ``diagnose``, the order search, the
input-hold choice and the yardstick print: per output, 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) (%), as
MATLAB's ``compare`` (1 − NRMSE). 100 % is a perfect simulation, 0 % is no better than the
output's mean, below 0 % is worse than the mean.

:func:`refit_flag` says why a refit's figure cannot be ranked: a model extended by an effect
that fits worse than the model it extends, or worse than the output's mean (below 0 %), or
whose simulation diverged, is flagged (``diagnose``'s findings, ``identify --add``) and never
ranked among the candidates.
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


#: the codes of :func:`refit_flag` (stable: they are in the JSON) and their words
REFIT_FLAGS = {
    "diverged": "its simulation diverged",
    "below_zero": "below 0 %: worse than the output's mean",
    "worse_than_base": "worse than the model it extends",
}


def refit_flag(fit_with: float, fit_base: float) -> str | None:
    """Why a refit's validation fit cannot be ranked, or None when it can.

    Parameters
    ----------
    fit_with : float
        Validation fit (%) of the model extended by an effect and refitted.
    fit_base : float
        Validation fit (%) of the model it extends, on the same samples.

    Returns
    -------
    str or None
        ``diverged`` (not a finite fit), ``below_zero`` (worse than the output's mean) or
        ``worse_than_base`` (a refit that lost fit: the extension made the fit worse);
        :data:`REFIT_FLAGS` words each.
    """
    fit_with = float(fit_with)
    if not np.isfinite(fit_with):
        return "diverged"
    if fit_with < 0.0:
        return "below_zero"
    if np.isfinite(fit_base) and fit_with < float(fit_base):
        return "worse_than_base"
    return None
