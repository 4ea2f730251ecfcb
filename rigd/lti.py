"""Exact discretisation of continuous linear systems ẋ = A x + B u (a leaf: numpy, scipy).

The one place the zero-order hold (input held between samples) and the first-order hold
(input linear between samples, "triangle hold") are written. Used by the identification
simulators (:mod:`rigd.ident.simulate`), the state-level effects
(:mod:`rigd.effects.state_level`) and the simulated plant (:mod:`rigd_drivers.sim_params`).

Both are the matrix exponential of one block matrix (Van Loan); ``expm`` is
:func:`scipy.linalg.expm` unless the caller passes a faster one for small matrices (the
identification passes its compiled kernel). A non-finite ``A`` or ``B`` (a fit probing wild
parameters) gives NaN matrices, never an exception.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg

Expm = Callable[[np.ndarray], np.ndarray]


def _expm_or_nan(M: np.ndarray, expm: Expm | None) -> np.ndarray:
    if not np.all(np.isfinite(M)):
        return np.full_like(M, np.nan)
    return (expm or scipy.linalg.expm)(M)


def zoh(A: np.ndarray, B: np.ndarray, dt: float, *,
        expm: Expm | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation: x[k+1] = Ad x[k] + Bd u[k].

    Parameters
    ----------
    A : ndarray (nx, nx)
        Continuous state matrix, 1/s.
    B : ndarray (nx, nu)
        Continuous input matrix.
    dt : float
        Sample period, s.
    expm : callable, optional
        Matrix exponential to use (default :func:`scipy.linalg.expm`).

    Returns
    -------
    Ad, Bd : ndarray
        C-contiguous; NaN if ``A`` or ``B`` is not finite.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    nx, nu = A.shape[0], B.shape[1]
    M = np.zeros((nx + nu, nx + nu))
    M[:nx, :nx] = A * dt
    M[:nx, nx:] = B * dt
    E = _expm_or_nan(M, expm)
    return np.ascontiguousarray(E[:nx, :nx]), np.ascontiguousarray(E[:nx, nx:])


def foh(A: np.ndarray, B: np.ndarray, dt: float, *,
        expm: Expm | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order-hold (input linear between samples) discretisation:
    x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1].

    Parameters and NaN policy as :func:`zoh`. Returns ``(Ad, B0, B1)``, C-contiguous.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    nx, nu = A.shape[0], B.shape[1]
    M = np.zeros((nx + 2 * nu, nx + 2 * nu))
    M[:nx, :nx] = A * dt
    M[:nx, nx:nx + nu] = B * dt
    M[nx:nx + nu, nx + nu:] = np.eye(nu)
    E = _expm_or_nan(M, expm)
    G1, G2 = E[:nx, nx:nx + nu], E[:nx, nx + nu:]
    return (np.ascontiguousarray(E[:nx, :nx]), np.ascontiguousarray(G1 - G2),
            np.ascontiguousarray(G2))
