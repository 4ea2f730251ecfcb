"""Exact discretisation of continuous linear systems ẋ = A x + B u (a leaf: numpy, scipy).

Also :func:`resonator`, one lightly damped mode as a discrete filter (Tustin, pre-warped).

The one place the zero-order hold (input held between samples) and the first-order hold
(input linear between samples, "triangle hold") are written. Used by the identification
simulators (:mod:`rigd.ident.simulate`), the state-level effects
(:mod:`rigd.effects.state_level`) and the simulated plant (:mod:`rigd_drivers.sim.params`).

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


def _balanced(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                       np.ndarray]:
    """(S⁻¹ A S, S⁻¹ B diag(1/b), s, b): a diagonal similarity S = diag(s) balancing A and
    column scales b bringing each input's column to A's size, all powers of two (exact).

    The exponential's scaling and squaring is as accurate as the block matrix's norm allows:
    an input in tiny units (B of 1e11) or a velocity state in another rate's units made
    the A part lose its digits (the fit's Jacobian then missed the damping: a record's input
    rescaled ×1e-6 fitted 1.2 points worse). Balanced, the result does not depend on the
    units of the inputs, states or time (docs/diagnose.md, "Invariance").
    """
    from scipy.linalg import matrix_balance

    _, (s, _) = matrix_balance(A, permute=False, separate=True)
    At = A * (s[None, :] / s[:, None])
    Bt = B / s[:, None]
    na = float(np.max(np.abs(At))) if At.size else 0.0
    nb = np.max(np.abs(Bt), axis=0) if Bt.size else np.ones(B.shape[1])
    ok = nb > 0
    b = np.ones(B.shape[1])
    b[ok] = 2.0 ** np.round(np.log2(nb[ok] / (na if na > 0 else 1.0)))
    return At, Bt / b[None, :], s, b


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
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        return np.full((nx, nx), np.nan), np.full((nx, nu), np.nan)
    At, Bt, sc, b = _balanced(A, B)
    M = np.zeros((nx + nu, nx + nu))
    M[:nx, :nx] = At * dt
    M[:nx, nx:] = Bt * dt
    E = _expm_or_nan(M, expm)
    return (np.ascontiguousarray(E[:nx, :nx] * (sc[:, None] / sc[None, :])),
            np.ascontiguousarray(E[:nx, nx:] * sc[:, None] * b[None, :]))


def foh(A: np.ndarray, B: np.ndarray, dt: float, *,
        expm: Expm | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order-hold (input linear between samples) discretisation:
    x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1].

    Parameters and NaN policy as :func:`zoh`. Returns ``(Ad, B0, B1)``, C-contiguous.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    nx, nu = A.shape[0], B.shape[1]
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        nan = np.full((nx, nu), np.nan)
        return np.full((nx, nx), np.nan), nan, nan.copy()
    At, Bt, sc, b = _balanced(A, B)
    M = np.zeros((nx + 2 * nu, nx + 2 * nu))
    M[:nx, :nx] = At * dt
    M[:nx, nx:nx + nu] = Bt * dt
    M[nx:nx + nu, nx + nu:] = np.eye(nu)
    E = _expm_or_nan(M, expm)
    back = sc[:, None] * b[None, :]
    G1, G2 = E[:nx, nx:nx + nu] * back, E[:nx, nx + nu:] * back
    return (np.ascontiguousarray(E[:nx, :nx] * (sc[:, None] / sc[None, :])),
            np.ascontiguousarray(G1 - G2), np.ascontiguousarray(G2))


def resonator(x: np.ndarray, f_hz: float, zeta: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Responses of a unit-DC-gain mode w^2/(s^2 + 2 zeta w s + w^2) and of s/w times it
    (its velocity, same units), discretised by Tustin pre-warped at f_hz."""
    # imported here: 3x scipy.linalg's import time (13 s at load 25), and every process of
    # the daemon imports this module (the drivers' parameter blocks)
    from scipy import signal

    w = 2 * np.pi * f_hz
    den = (1.0, 2 * zeta * w, w * w)
    fw = min(f_hz, 0.45 * fs)
    k = 2.0 * fs if fw <= 0 else _prewarp_k(fs, fw)
    bd, ad = _bilinear2((0.0, 0.0, w * w), den, k)
    bv, av = _bilinear2((0.0, w, 0.0), den, k)
    return signal.lfilter(bd, ad, x), signal.lfilter(bv, av, x)


def _prewarp_k(fs: float, f_hz: float) -> float:
    """The Tustin map's k in s -> k (z-1)/(z+1), pre-warped so that f_hz maps exactly."""
    w = 2 * np.pi * f_hz
    return w / np.tan(w / (2 * fs))


def _bilinear2(num, den, k: float) -> tuple[np.ndarray, np.ndarray]:
    """(b0 s^2 + b1 s + b2)/(a0 s^2 + a1 s + a2) with s = k (z-1)/(z+1), as z-polynomials
    normalised to a monic denominator: scipy.signal.bilinear's result for second order, in
    closed form (the generic one expands polynomials; a mode's fit calls this thousands of
    times)."""
    k2 = k * k

    def z(c):
        c0, c1, c2 = c
        return (c0 * k2 + c1 * k + c2, 2.0 * (c2 - c0 * k2), c0 * k2 - c1 * k + c2)

    b, a = z(num), z(den)
    return np.array(b) / a[0], np.array(a) / a[0]
