"""Discretisation at the loop rate: Tustin for K∞(s) → K∞(z) (paper Sec. 5, Fig. 5), ZOH for
plant models.

The bilinear map s = c (z − 1)/(z + 1), c = 2·fs (plain) or c = ω_p / tan(ω_p T/2) (prewarped:
K(z) equals K(s) exactly at ω_p, e.g. the centre of the damping band), is applied to a
well-conditioned realization: the controller is taken to the frequency-scaled time unit
(:data:`rigd.design.hinf.OMEGA_SCALE`) and diagonally balanced (SLICOT TB01ID) first, and the
only matrix inverted is I − A/c, whose condition number then stays small. (scipy's
``cont2discrete`` on the raw 32-state product H_hp·K̃ warned ``rcond = 1.9e-19``.)
"""

from __future__ import annotations

import numpy as np

from rigd.design.hinf import OMEGA_SCALE


def bilinear_constant(fs_hz: float, prewarp_hz: float | None = None) -> float:
    """c (rad/s) of s = c (z − 1)/(z + 1)."""
    T = 1.0 / fs_hz
    if prewarp_hz is None:
        return 2.0 / T
    return 2 * np.pi * prewarp_hz / np.tan(np.pi * prewarp_hz * T)


def warp(f_hz, fs_hz: float, prewarp_hz: float | None = None) -> np.ndarray:
    """ω (rad/s) with K(z = e^{j2πf/fs}) = K(s = jω) for the Tustin K(z) of K(s)."""
    return bilinear_constant(fs_hz, prewarp_hz) * np.tan(np.pi * np.asarray(f_hz, float) / fs_hz)


def tustin_matrices(A, B, C, D, fs_hz: float, prewarp_hz: float | None = None,
                    scale: float = 1.0):
    """(Ad, Bd, Cd, Dd) of the Tustin K(z) of K(s) = C (sI − A·scale)⁻¹ B·scale + D.

    ``scale`` is the time unit of (A, B): A·scale is in rad/s (``scale`` = ω_s for matrices in
    the scaled unit s' = s/ω_s).
    """
    A, B, C, D = (np.asarray(v, float) for v in (A, B, C, D))
    cs = bilinear_constant(fs_hz, prewarp_hz) / scale
    n = A.shape[0]
    M = np.eye(n) - A / cs
    Ad = np.linalg.solve(M, np.eye(n) + A / cs)
    QB = np.linalg.solve(M, B)
    Bd = QB * (2.0 / cs)
    Cd = np.linalg.solve(M.T, C.T).T
    Dd = D + C @ QB / cs
    return Ad, Bd, Cd, Dd


def balanced_scaled(K):
    """(A, B, C, D) of a continuous K in the scaled time unit, diagonally balanced (TB01ID)."""
    from slycot import tb01id

    w = OMEGA_SCALE
    A, B, C = np.asarray(K.A, float) / w, np.asarray(K.B, float) / w, np.asarray(K.C, float)
    n = A.shape[0]
    if n:
        _s, A, B, C, _d = tb01id(n, B.shape[1], C.shape[0], 10.0, A.copy(), B.copy(), C.copy(),
                                 job="A")
    return A, B, C, np.asarray(K.D, float)


def tustin(K, fs_hz: float, prewarp_hz: float | None = None):
    """K∞(z) = K∞(s) with s = c (z − 1)/(z + 1) (see module docstring).

    Parameters
    ----------
    K : control.StateSpace
        Continuous controller.
    fs_hz : float
        Loop rate (Hz); the result has ``dt = 1/fs_hz``.
    prewarp_hz : float, optional
        Frequency (Hz) at which K(z) matches K(s) exactly (e.g. the centre of the damping
        band); ``None``: plain bilinear transform.
    """
    import control

    Ad, Bd, Cd, Dd = tustin_matrices(*balanced_scaled(K), fs_hz, prewarp_hz, OMEGA_SCALE)
    return control.ss(Ad, Bd, Cd, Dd, 1.0 / fs_hz)


def zoh(G, fs_hz: float):
    """Zero-order-hold G(z) of a continuous plant model at ``fs_hz`` (G itself if discrete)."""
    import control

    return G if G.dt else control.c2d(G, 1.0 / fs_hz, method="zoh")
