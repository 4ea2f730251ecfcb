"""Small signal helpers shared by the effect modules (all causal, float64, (n,) arrays)."""

from __future__ import annotations

import numba
import numpy as np
from scipy import signal


def derivative(x: np.ndarray, fs: float) -> np.ndarray:
    """Time derivative (units/s) by central differences along axis 0."""
    return np.gradient(np.asarray(x, float), 1.0 / fs, axis=0)


def lag1(x: np.ndarray, tau: float, fs: float) -> np.ndarray:
    """First-order lag 1/(tau s + 1), exact for a piecewise-linear input, starting at rest
    on x[0]; tau = 0 returns x."""
    x = np.asarray(x, float)
    if tau <= 0:
        return x.copy()
    dt = 1.0 / fs
    a = np.exp(-dt / tau)
    c = (tau / dt) * (1.0 - a)
    b0, b1 = 1.0 - c, c - a
    zi = signal.lfiltic([b0, b1], [1.0, -a], y=[x[0]], x=[x[0]])
    return signal.lfilter([b0, b1], [1.0, -a], x, zi=zi)[0]


def shift(x: np.ndarray, d: float) -> np.ndarray:
    """x delayed by d >= 0 samples (linear interpolation, held at x[0] before the start)."""
    x = np.asarray(x, float)
    if d <= 0:
        return x.copy()
    n = x.shape[0]
    t = np.arange(n) - d
    return np.interp(t, np.arange(n), x, left=x[0])


@numba.njit(cache=True)
def play(x: np.ndarray, w: float) -> np.ndarray:
    """Play (backlash) operator of width w: the elementary hysteron of Prandtl-Ishlinskii."""
    y = np.empty_like(x)
    h = 0.5 * w
    prev = x[0]
    for k in range(x.shape[0]):
        v = x[k]
        if v - prev > h:
            prev = v - h
        elif prev - v > h:
            prev = v + h
        y[k] = prev
    return y


def band_power_share(x: np.ndarray, fs: float, f_lo: float, f_hi: float) -> float:
    """Share of the (mean-removed) signal power between f_lo and f_hi, Hz."""
    x = np.asarray(x, float) - np.mean(x)
    n = x.shape[0]
    if n < 8 or not np.any(x):
        return 0.0
    f, p = signal.welch(x, fs=fs, nperseg=min(n, 4096))
    tot = np.sum(p)
    return float(np.sum(p[(f >= f_lo) & (f <= f_hi)]) / tot) if tot > 0 else 0.0


def n_levels(x: np.ndarray, tol: float = 0.02) -> int:
    """Number of distinct levels that hold >= 2 % of the samples (clusters within tol of the
    signal range): 2 for a two-level PRBS, many for noise or multi-level sequences."""
    x = np.asarray(x, float)
    span = np.ptp(x)
    if span == 0:
        return 1
    q = np.round((x - x.min()) / (tol * span)).astype(np.int64)
    counts = np.bincount(q)
    share = counts / x.shape[0]
    if np.sum(share[share >= 0.02]) < 0.9:  # spread out: a continuum of levels
        return int(1 / tol)
    return int(np.sum(share >= 0.02))


def spread(x: np.ndarray) -> np.ndarray:
    """Half the 1–99 % percentile span per column (a robust half-amplitude, in the channel's
    unit); 1 for a constant column so that ratios stay finite."""
    x = np.atleast_2d(np.asarray(x, float).T).T
    lo, hi = np.percentile(x, [1.0, 99.0], axis=0)
    s = 0.5 * (hi - lo)
    return np.where(s > 0, s, 1.0)
