"""Least-squares ARX models, any number of inputs and outputs (a black-box reference).

    y[t] + a_1 y[t−1] + … + a_na y[t−na] = Σ_j Σ_{i<nb_j} b_{j,i} u_j[t − nk_j − i] + e[t]

with matrix coefficients a_k (ny × ny) and b_{j,i} (ny,) per input ``j`` (MATLAB's ``arx``
with ``[na nb nk]``), on deviations from the estimation data's means. The fit is one linear
least-squares problem (accumulated QR, :mod:`.lsq`); the model converts to the innovation
form :class:`~rigd.ident.lti.linear.LinearModel` (observer canonical form, K = −a), which
simulates free-run, predicts one step ahead, and gives the held-out figure
(:func:`~rigd.ident.lti.linear.heldout`).

:func:`select_arx` picks the order (na = nb_j = n) on the estimation data alone: each order
is fitted on its first two thirds and scored by the free-run fit on its last third; the best
is refitted on all of it. The input delays nk_j come from :func:`rigd.ident.lti.delay.
estimate_delays` unless given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rigd.ident.lti.linear import LinearModel, as_2d, heldout
from rigd.ident.lti.lsq import solve_r, stacked_r


def _per_input(v: int | Sequence[int], nu: int, what: str) -> tuple[int, ...]:
    t = (int(v),) * nu if np.isscalar(v) else tuple(int(x) for x in v)
    if len(t) != nu or min(t, default=0) < 0:
        raise ValueError(f"{what}: one non-negative integer per input ({nu}) expected, got {v}")
    return t


@dataclass
class ArxModel:
    """A fitted ARX model (module docstring).

    Attributes
    ----------
    na : int
    nb, nk : tuple of int
        Per input: number of b coefficients, and delay (samples) of the first.
    a : ndarray (na, ny, ny)
        a_1 … a_na.
    b : ndarray (L + 1, ny, nu)
        Input coefficients by lag 0 … L (zero outside each input's nk_j … nk_j + nb_j − 1).
    u0, y0 : ndarray
        Means removed before the fit (estimation data).
    fs : float or None
        Sample rate (Hz).
    """

    na: int
    nb: tuple[int, ...]
    nk: tuple[int, ...]
    a: np.ndarray
    b: np.ndarray
    u0: np.ndarray
    y0: np.ndarray
    fs: float | None = None

    def to_linear(self) -> LinearModel:
        """The same model as :class:`LinearModel` (observer form; the ARX predictor is its
        Kalman predictor, K = −[a_1; …; a_L])."""
        ny, nu = self.b.shape[1], self.b.shape[2]
        L = max(self.na, self.b.shape[0] - 1, 1)
        a = np.zeros((L + 1, ny, ny))
        a[1:self.na + 1] = self.a
        b = np.zeros((L + 1, ny, nu))
        b[:self.b.shape[0]] = self.b
        nx = ny * L
        A = np.zeros((nx, nx))
        B = np.zeros((nx, nu))
        K = np.zeros((nx, ny))
        for k in range(1, L + 1):
            r = slice((k - 1) * ny, k * ny)
            A[r, :ny] = -a[k]
            if k < L:
                A[r, k * ny:(k + 1) * ny] = np.eye(ny)
            B[r] = b[k] - a[k] @ b[0]
            K[r] = -a[k]
        C = np.zeros((ny, nx))
        C[:, :ny] = np.eye(ny)
        return LinearModel(A, B, C, b[0].copy(), K, np.zeros(nx), self.u0.copy(),
                           self.y0.copy(), self.fs)


def fit_arx(u: np.ndarray, y: np.ndarray, na: int, nb: int | Sequence[int],
            nk: int | Sequence[int] = 1, fs: float | None = None) -> ArxModel:
    """Least-squares ARX model of u → y.

    Parameters
    ----------
    u, y : ndarray (n,) or (n, nu), (n,) or (n, ny)
        Estimation data, any units.
    na : int
        Output lags.
    nb, nk : int or sequence of int
        Per input (a single value for all): number of b coefficients and delay (samples).
    fs : float, optional
        Sample rate (Hz), kept for readouts.
    """
    u, y = as_2d(u), as_2d(y)
    n, nu = u.shape
    ny = y.shape[1]
    nb, nk = _per_input(nb, nu, "nb"), _per_input(nk, nu, "nk")
    if na < 0:
        raise ValueError(f"na must be >= 0, got {na}")
    u0, y0 = u.mean(0), y.mean(0)
    du, dy = u - u0, y - y0
    lb = max((k + b - 1 for k, b in zip(nk, nb) if b > 0), default=0)
    lag = max(na, lb)
    d = na * ny + sum(nb)
    if n - lag <= 2 * d:
        raise ValueError(f"record too short for an ARX model with {d} parameters ({n} samples)")

    def rows(t0, t1):
        t = np.arange(lag + t0, lag + t1)
        cols = [-dy[t - k] for k in range(1, na + 1)]
        for j in range(nu):
            cols += [du[t - nk[j] - i, j:j + 1] for i in range(nb[j])]
        return np.hstack(cols + [dy[t]])

    theta = solve_r(stacked_r(rows, n - lag, d + ny), d)   # (d, ny)
    a = np.stack([theta[k * ny:(k + 1) * ny].T for k in range(na)]) if na else \
        np.zeros((0, ny, ny))
    b = np.zeros((lb + 1, ny, nu))
    p = na * ny
    for j in range(nu):
        for i in range(nb[j]):
            b[nk[j] + i, :, j] = theta[p]
            p += 1
    return ArxModel(int(na), nb, nk, a, b, u0, y0, fs)


@dataclass
class ArxSelection:
    """Result of :func:`select_arx`: the model refitted on all the estimation data, its
    order, and the check fit (%) of every order tried (−inf: diverged)."""

    model: ArxModel
    order: int
    nk: tuple[int, ...]
    check_fit: dict[int, float]   # per order, the best over the delays tried


def select_arx(u: np.ndarray, y: np.ndarray, orders: Sequence[int] = tuple(range(1, 11)),
               nk: int | Sequence[int] | None = None, fs: float | None = None) -> ArxSelection:
    """ARX model with na = nb_j = n chosen on the estimation data (u, y) alone.

    Each n in ``orders`` is fitted on the first two thirds and scored by the mean free-run
    fit on the last third (:func:`~rigd.ident.lti.linear.heldout`); the best is refitted on
    all of (u, y). ``nk`` defaults to the delays chosen with the order: the lags of
    :func:`rigd.ident.lti.delay.estimate_delays`, fractions of them (0, ¼, ½, ¾: the first
    significant lag of a response of high relative degree comes late, so the estimate can be
    far too long) and one sample more, each with every order, by the same check fit.
    """
    from rigd.ident.lti.delay import estimate_delays

    u, y = as_2d(u), as_2d(y)
    if nk is None:
        est = [d.nk for d in estimate_delays(u, y)]
        tries = {tuple(int(round(f * k)) for k in est) for f in (0.0, 0.25, 0.5, 0.75, 1.0)}
        tries.add(tuple(k + 1 for k in est))
    else:
        tries = {_per_input(nk, u.shape[1], "nk")}
    cut = (2 * len(u)) // 3
    scores: dict[int, float] = {}
    best, best_key = None, None
    for lags in sorted(tries):
        lags = _per_input(lags, u.shape[1], "nk")
        for n in orders:
            try:
                m = fit_arx(u[:cut], y[:cut], n, n, lags, fs).to_linear()
            except (ValueError, np.linalg.LinAlgError):
                continue
            fit, _ = heldout(m, u, y, cut)
            f = float(np.mean(fit))
            key = (f, -n, -sum(lags))
            if best_key is None or key > best_key:
                best, best_key = (n, lags), key
            scores[int(n)] = max(scores.get(int(n), -np.inf), f)
    if best is None:
        raise ValueError(f"record too short for any ARX order in {tuple(orders)} "
                         f"({len(u)} samples)")
    n, lags = best
    return ArxSelection(fit_arx(u, y, n, n, lags, fs), n, lags, scores)
