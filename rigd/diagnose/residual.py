"""Residual analysis: where a model fails (time, amplitude, angle, direction, frequency) and
MATLAB-``resid``-style whiteness and residual–input independence tests.

All functions take plain arrays: residual ``r`` (n,) or (n, ny), inputs ``u`` (n, nu),
sample rate ``fs`` (Hz). Confidence bounds are two-sided at ``conf`` (default 99 %, as
``resid``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal, stats

from rigd.ident.thresholds import CORR_CONFIDENCE


def _z(conf: float) -> float:
    return float(stats.norm.ppf(0.5 + conf / 2))


def _acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    x = x - x.mean()
    n = x.shape[0]
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, nfft)
    ac = np.fft.irfft(f * np.conj(f), nfft)[:max_lag + 1]
    return ac / ac[0] if ac[0] > 0 else np.zeros(max_lag + 1)


@dataclass
class CorrTest:
    """Correlation test result: ``lags``, ``rho`` (normalised), ``bound`` (±), ``passed``
    (share of lags outside the bound at most ``1 - conf`` + 2 lags of slack)."""

    lags: np.ndarray
    rho: np.ndarray
    bound: float
    outside: float
    passed: bool


def whiteness(r: np.ndarray, max_lag: int = 25, conf: float = CORR_CONFIDENCE) -> CorrTest:
    """Autocorrelation of the residual at lags 1..max_lag with bound z/√N."""
    r = np.asarray(r, float)
    rho = _acf(r, max_lag)[1:]
    bound = _z(conf) / np.sqrt(r.shape[0])
    out = float(np.mean(np.abs(rho) > bound))
    return CorrTest(np.arange(1, max_lag + 1), rho, bound, out,
                    out <= (1 - conf) + 2.0 / max_lag)


def cross_correlation(r: np.ndarray, u: np.ndarray, max_lag: int = 25,
                      conf: float = CORR_CONFIDENCE) -> CorrTest:
    """Residual–input cross-correlation at lags −max_lag..max_lag (positive: input leads).

    The bound accounts for the autocorrelation of both series (as ``resid``):
    z·sqrt(Σ_k ρ_rr(k) ρ_uu(k)) / √N.
    """
    r = np.asarray(r, float) - np.mean(r)
    u = np.asarray(u, float) - np.mean(u)
    n = r.shape[0]
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    c = np.fft.irfft(np.fft.rfft(r, nfft) * np.conj(np.fft.rfft(u, nfft)), nfft)
    den = np.sqrt(np.sum(r ** 2) * np.sum(u ** 2)) or 1.0
    lags = np.arange(-max_lag, max_lag + 1)
    rho = c[lags % nfft] / den
    L = min(max_lag, n - 1)
    arr, auu = _acf(r, L), _acf(u, L)
    P = arr[0] * auu[0] + 2 * np.sum(arr[1:] * auu[1:])
    bound = _z(conf) * np.sqrt(max(P, 1.0)) / np.sqrt(n)
    out = float(np.mean(np.abs(rho) > bound))
    return CorrTest(lags, rho, bound, out, out <= (1 - conf) + 2.0 / len(lags))


def spectra(r: np.ndarray, y: np.ndarray, fs: float, nperseg: int | None = None):
    """Welch PSDs of the residual and of the measured output: (f, P_rr, P_yy)."""
    n = np.asarray(r).shape[0]
    nper = int(min(n, nperseg or 2 ** int(np.log2(max(min(n // 8, 8192), 64)))))
    f, prr = signal.welch(r, fs=fs, nperseg=nper, axis=0)
    _, pyy = signal.welch(np.asarray(y) - np.mean(y, axis=0), fs=fs, nperseg=nper, axis=0)
    return f, prr, pyy


def by_segment(r: np.ndarray, nseg: int = 20) -> np.ndarray:
    """Residual RMS in ``nseg`` consecutive segments (all outputs pooled)."""
    r = np.atleast_2d(np.asarray(r, float).T).T
    parts = np.array_split(np.arange(r.shape[0]), nseg)
    return np.array([np.sqrt(np.mean(r[p] ** 2)) for p in parts])


def by_amplitude(r: np.ndarray, a: np.ndarray, nbins: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Residual RMS per quantile bin of amplitude ``a`` (n,): (bin edges, rms)."""
    r = np.atleast_2d(np.asarray(r, float).T).T
    a = np.asarray(a, float)
    edges = np.quantile(a, np.linspace(0, 1, nbins + 1))
    idx = np.clip(np.searchsorted(edges, a, side="right") - 1, 0, nbins - 1)
    rms = np.array([np.sqrt(np.mean(r[idx == b] ** 2)) if np.any(idx == b) else 0.0
                    for b in range(nbins)])
    return edges, rms


def by_angle(r: np.ndarray, phi: np.ndarray, nbins: int = 36) -> tuple[np.ndarray, np.ndarray]:
    """Mean residual per shaft-angle bin: (bin centres rad, mean (nbins, ny))."""
    r = np.atleast_2d(np.asarray(r, float).T).T
    ph = np.mod(np.asarray(phi, float), 2 * np.pi)
    idx = np.minimum((ph / (2 * np.pi) * nbins).astype(int), nbins - 1)
    cnt = np.maximum(np.bincount(idx, minlength=nbins), 1)
    mean = np.column_stack([np.bincount(idx, weights=r[:, i], minlength=nbins) / cnt
                            for i in range(r.shape[1])])
    return (np.arange(nbins) + 0.5) * 2 * np.pi / nbins, mean


def by_direction(r: np.ndarray, u: np.ndarray) -> dict[str, np.ndarray]:
    """Mean and RMS residual (per output) while input ``u`` (n,) rises, falls or holds."""
    r = np.atleast_2d(np.asarray(r, float).T).T
    du = np.gradient(np.asarray(u, float))
    tol = 1e-9 * (np.ptp(u) or 1.0)
    out = {}
    for name, m in (("rising", du > tol), ("falling", du < -tol), ("holding", np.abs(du) <= tol)):
        out[name] = (r[m].mean(axis=0) if m.any() else np.zeros(r.shape[1]))
        out[name + "_n"] = int(m.sum())
    return out


def spectral_peaks(r: np.ndarray, fs: float, min_share: float = 0.05,
                   ratio: float = 10.0) -> list[dict]:
    """Narrow peaks of the residual PSD above its smoothed floor that carry at least
    ``min_share`` of the residual power: [{"frequency_hz", "share"}]."""
    r = np.atleast_2d(np.asarray(r, float).T).T
    n = r.shape[0]
    nper = int(min(n, 2 ** int(np.log2(max(min(n // 8, 4096), 64)))))
    f, p = signal.welch(r, fs=fs, nperseg=nper, axis=0)
    p = p.sum(axis=1)
    floor = signal.medfilt(p, 31 if len(p) > 31 else (len(p) // 2) * 2 - 1 or 1)
    tot = np.sum(p) or 1.0
    out = []
    k = 1
    while k < len(p) - 1:
        if p[k] > ratio * max(floor[k], 1e-300) and p[k] >= p[k - 1] and p[k] >= p[k + 1]:
            lo, hi = max(0, k - 3), min(len(p), k + 4)
            share = float(np.sum(p[lo:hi] - floor[lo:hi]) / tot)
            if share >= min_share:
                out.append({"frequency_hz": float(f[k]), "share": share})
            k = hi
        else:
            k += 1
    return sorted(out, key=lambda d: -d["share"])
