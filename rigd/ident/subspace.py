"""Subspace identification (N4SID, Van Overschee & De Moor 1994): a non-iterative linear
state-space estimate of a given order, used as the initial estimate of higher-order models.

Written here in numpy (≈ 60 lines) instead of taking a library: the maintained Python
packages with N4SID (SIPPY, nfoursid) pull in plotting/pandas stacks or are unmaintained,
and only the dynamics matrix A (its poles) is needed — the gains are then fitted by linear
least squares and the whole model refined by output error (:mod:`rigd.ident.order`).

The data are normalised to unit standard deviation per channel first, so the result does
not depend on the units of the channels; the poles are returned in the discrete domain and,
with :func:`continuous_modes`, as natural frequencies relative to the sample rate given.
"""

from __future__ import annotations

import numpy as np


def _hankel(x: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    """Block Hankel matrix (rows·m × cols) of the (n, m) signal x from sample ``start``."""
    m = x.shape[1]
    H = np.empty((rows * m, cols))
    for i in range(rows):
        H[i * m:(i + 1) * m] = x[start + i:start + i + cols].T
    return H


def n4sid_a(u: np.ndarray, y: np.ndarray, order: int, horizon: int | None = None,
            max_cols: int = 20_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dynamics and output matrices (A, C) of an ``order``-state model of u -> y (N4SID).

    Parameters
    ----------
    u, y : ndarray (n, nu), (n, ny)
        Input and output samples (any units; normalised inside).
    order : int
        Number of states.
    horizon : int, optional
        Block rows of the past/future Hankel matrices (default max(2·order, 8) + 2).
    max_cols : int
        Columns of the Hankel matrices used (the latest ``max_cols``; bounds the cost).

    Returns
    -------
    A : ndarray (order, order)
        Discrete dynamics matrix.
    C : ndarray (ny, order)
        Output matrix (normalised output units).
    sv : ndarray
        Singular values of the weighted oblique projection (order selection aid).
    """
    u = np.atleast_2d(np.asarray(u, float).T).T
    y = np.atleast_2d(np.asarray(y, float).T).T
    u = (u - u.mean(0)) / np.maximum(u.std(0), 1e-300)
    y = (y - y.mean(0)) / np.maximum(y.std(0), 1e-300)
    n, ny = y.shape
    i = int(horizon or max(2 * order, 8) + 2)
    j = n - 2 * i + 1
    if j < 4 * i * (u.shape[1] + ny):
        raise ValueError(f"record too short for a subspace estimate of order {order} "
                         f"({n} samples)")
    s = max(0, j - max_cols)
    j -= s
    Up, Uf = _hankel(u, s, i, j), _hankel(u, s + i, i, j)
    Yp, Yf = _hankel(y, s, i, j), _hankel(y, s + i, i, j)
    Wp = np.vstack([Up, Yp])
    # project out the future inputs (orthogonal complement of Uf), via a QR of Ufᵀ
    Q, _ = np.linalg.qr(Uf.T)

    def perp(M):
        return M - (M @ Q) @ Q.T

    Yfp, Wpp = perp(Yf), perp(Wp)
    G = Wpp @ Wpp.T
    L = np.linalg.lstsq(G, (Yfp @ Wpp.T).T, rcond=None)[0].T   # Yf/Uf⊥ · (Wp/Uf⊥)⁺
    # oblique projection O = L·Wp; its column space from the SVD of L·chol(Wp Wpᵀ)
    R = np.linalg.cholesky(Wp @ Wp.T / j + 1e-12 * np.eye(Wp.shape[0]))
    U1, sv, _ = np.linalg.svd(L @ R, full_matrices=False)
    Gam = U1[:, :order] * np.sqrt(sv[:order])
    A = np.linalg.lstsq(Gam[:-ny], Gam[ny:], rcond=None)[0]
    C = Gam[:ny]
    return A, C, sv


def continuous_modes(A: np.ndarray, fs: float) -> list[tuple[float, float]]:
    """Oscillatory modes (f_n in Hz, ζ) of the discrete dynamics matrix ``A`` at rate ``fs``:
    complex pole pairs below 0.95·Nyquist with 0 < ζ < 1, slowest first."""
    lam = np.linalg.eigvals(A)
    out = []
    for z in lam:
        if z.imag <= 1e-9 or abs(z) <= 0:
            continue
        s = np.log(z) * fs
        wn = abs(s)
        zeta = -s.real / wn
        f = wn / (2 * np.pi)
        if 0 < zeta < 1 and f < 0.95 * fs / 2:
            out.append((float(f), float(zeta)))
    return sorted(out)
