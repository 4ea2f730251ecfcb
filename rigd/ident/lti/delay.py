"""Per-input delay of a record, estimated before any model order is chosen.

Two independent estimates per input ``j``, each the first lag at which the input visibly
acts on some output:

* **ARX impulse response**: an ARX model with ``na`` = :data:`NA` and b coefficients at lags
  0 … ``max_lag`` for every input (:func:`rigd.ident.lti.arx`'s regression); the first lag
  whose coefficient's t-statistic exceeds :data:`T_LEVEL` on any output;
* **prewhitened cross-correlation**: an AR(:data:`AR_ORDER`) filter that whitens u_j is
  applied to u_j and to each output; the first lag at which their normalised
  cross-correlation exceeds :data:`T_LEVEL`/√N.

The returned ``nk`` is a discrete lag: the first sample of the response to a step of u_j is
y[t0 + nk]. For a continuous plant sampled through a zero-order hold, a transport delay of τ
samples gives nk = ⌊τ⌋ + 1 (τ ∈ [nk − 1, nk)), which :attr:`DelayEstimate.delay_zoh` reports;
an instantaneous (measured, first-order-hold) input gives nk = ⌈τ⌉.

``confidence`` (0 … 1): 1 when both estimates agree, 0.6 when they differ by one sample,
0.4 when only one is significant or they differ more (the earlier one is then kept), 0 when
neither shows the input acting (nk = 0 reported).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from rigd.ident.lti.linear import as_2d
from rigd.ident.lti.lsq import stacked_r

#: output lags of the ARX model whose b coefficients give the impulse response (enough for
#: several modes: a model too low in order leaves a residual that hides the first lags)
NA = 8
#: order of the AR model that prewhitens each input
AR_ORDER = 10
#: |t| (or √N·|ρ|) above which a lag counts as the input acting (≈ 1e-4 two-sided, several
#: dozen lags tested)
T_LEVEL = 4.0


@dataclass
class DelayEstimate:
    """Delay of one input (module docstring).

    Attributes
    ----------
    nk : int
        Lag (samples) of the first significant response.
    confidence : float
        0 … 1, agreement of the two estimates.
    nk_arx, nk_xcorr : int or None
        The two estimates (None: nothing significant up to the largest lag tried).
    """

    nk: int
    confidence: float
    nk_arx: int | None
    nk_xcorr: int | None

    @property
    def delay_zoh(self) -> int:
        """Transport delay (samples) of a strictly proper plant behind a zero-order hold."""
        return max(self.nk - 1, 0)


def _first(mask: np.ndarray) -> int | None:
    hit = np.flatnonzero(mask)
    return int(hit[0]) if hit.size else None


def _arx_first_lags(du, dy, max_lag):
    """First significant b lag per input (None: none), from one ARX regression."""
    n, nu = du.shape
    ny = dy.shape[1]
    lag = max(NA, max_lag)
    d = NA * ny + nu * (max_lag + 1)

    def rows(t0, t1):
        t = np.arange(lag + t0, lag + t1)
        cols = [-dy[t - k] for k in range(1, NA + 1)]
        cols += [du[t - i, j:j + 1] for j in range(nu) for i in range(max_lag + 1)]
        return np.hstack(cols + [dy[t]])

    R = stacked_r(rows, n - lag, d + ny)
    R11 = R[:d, :d]
    theta = np.linalg.lstsq(R11, R[:d, d:], rcond=None)[0]
    dof = max(n - lag - d, 1)
    sigma2 = np.sum(R[d:, d:] ** 2, axis=0) / dof      # residual variance per output
    Rinv = np.linalg.pinv(R11)
    var = np.sum(Rinv ** 2, axis=1)                     # diag((R11ᵀR11)⁻¹)
    t = np.abs(theta) / np.sqrt(np.maximum(var[:, None] * sigma2[None, :], 1e-300))
    out = []
    for j in range(nu):
        tj = t[NA * ny + j * (max_lag + 1):NA * ny + (j + 1) * (max_lag + 1)]
        out.append(_first(np.any(tj > T_LEVEL, axis=1)))
    return out


def _xcorr_first_lag(uj, dy, max_lag):
    """First lag with a significant prewhitened cross-correlation u_j → any output."""
    n = len(uj)
    p = min(AR_ORDER, n // 20)
    if p >= 1:
        X = np.column_stack([uj[p - k:n - k] for k in range(1, p + 1)])
        a = np.linalg.lstsq(X, uj[p:], rcond=None)[0]
        filt = np.concatenate([[1.0], -a])
    else:
        filt = np.ones(1)
    alpha = scipy.signal.lfilter(filt, [1.0], uj)[p:]
    sa = np.std(alpha)
    if sa <= 0:
        return None
    m = len(alpha)
    hits = np.zeros(max_lag + 1, bool)
    for i in range(dy.shape[1]):
        beta = scipy.signal.lfilter(filt, [1.0], dy[:, i])[p:]
        sb = np.std(beta)
        if sb <= 0:
            continue
        r = np.array([np.dot(alpha[:m - k], beta[k:]) / (m * sa * sb)
                      for k in range(max_lag + 1)])
        hits |= np.abs(r) * np.sqrt(m) > T_LEVEL
    return _first(hits)


def estimate_delays(u: np.ndarray, y: np.ndarray, max_lag: int | None = None
                    ) -> list[DelayEstimate]:
    """Delay of each input of (u, y) in samples (module docstring).

    Parameters
    ----------
    u, y : ndarray (n,) or (n, nu), (n,) or (n, ny)
        Estimation data, any units.
    max_lag : int, optional
        Largest lag tried (default min(40, n // 50), at least 3).
    """
    u, y = as_2d(u), as_2d(y)
    n, nu = u.shape
    if max_lag is None:
        max_lag = max(3, min(40, n // 50))
    du, dy = u - u.mean(0), y - y.mean(0)
    arx = _arx_first_lags(du, dy, max_lag)
    out = []
    for j in range(nu):
        a, x = arx[j], _xcorr_first_lag(du[:, j], dy, max_lag)
        if a is None and x is None:
            out.append(DelayEstimate(0, 0.0, a, x))
        elif a is None or x is None:
            out.append(DelayEstimate(a if a is not None else x, 0.4, a, x))
        else:
            conf = 1.0 if a == x else 0.6 if abs(a - x) == 1 else 0.4
            out.append(DelayEstimate(a if conf > 0.4 else min(a, x), conf, a, x))
    return out
