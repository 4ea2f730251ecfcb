"""Numba-compiled kernels of the mechanical simulators (``cache=True``, no per-sample allocation).

:func:`lsim_kernel` (linear simulation), :func:`predict_kernel` (one-step-ahead predictor in
innovation form), :func:`cubic_kernel` (RK4 with cubic stiffness, simulation or predictor)
and :func:`expm_kernel` (matrix exponential for the exact discretisations). Used by
:mod:`rigd.ident.simulate`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


# --------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------
@njit(cache=True)
def lsim_kernel(Ad, Bd, C, x0, u, y):  # pragma: no cover - compiled
    """x[k+1] = Ad x[k] + Bd u[k],  y[k] = C x[k]; writes ``y`` (n, ny) in place."""
    n = u.shape[0]
    nx = Ad.shape[0]
    nu = Bd.shape[1]
    ny = C.shape[0]
    x = x0.copy()
    xn = np.empty(nx)
    for k in range(n):
        for i in range(ny):
            s = 0.0
            for j in range(nx):
                s += C[i, j] * x[j]
            y[k, i] = s
        for i in range(nx):
            s = 0.0
            for j in range(nx):
                s += Ad[i, j] * x[j]
            for j in range(nu):
                s += Bd[i, j] * u[k, j]
            xn[i] = s
        for i in range(nx):
            x[i] = xn[i]


@njit(cache=True)
def predict_kernel(Ad, Bd, Kd, C, x0, u, ymeas, yhat):  # pragma: no cover - compiled
    """One-step-ahead predictor in innovation form.

    x̂[k+1] = Ad x̂[k] + Bd u[k] + Kd (y[k] - C x̂[k]),  ŷ[k] = C x̂[k]; writes ``yhat``.
    """
    n = u.shape[0]
    nx = Ad.shape[0]
    nu = Bd.shape[1]
    ny = C.shape[0]
    x = x0.copy()
    xn = np.empty(nx)
    e = np.empty(ny)
    for k in range(n):
        for i in range(ny):
            s = 0.0
            for j in range(nx):
                s += C[i, j] * x[j]
            yhat[k, i] = s
            e[i] = ymeas[k, i] - s
        for i in range(nx):
            s = 0.0
            for j in range(nx):
                s += Ad[i, j] * x[j]
            for j in range(nu):
                s += Bd[i, j] * u[k, j]
            for j in range(ny):
                s += Kd[i, j] * e[j]
            xn[i] = s
        for i in range(nx):
            x[i] = xn[i]


@njit(cache=True, inline="always")
def _accel(K, D, k3, k3x, fr, p, v, f, df, tau, a):  # pragma: no cover - compiled
    """Acceleration at force f + tau·df (df: force change over the sample, FOH).

    Cubic force on axis i: k3_i p_i³ + k3x_i (Σ_{j≠i} p_j²) p_i (k3x = k3: radial, |p|² p);
    dry (Coulomb) friction fr[0, i] tanh(v_i / fr[1, i]) (smoothed sign, fr[1] > 0 where
    fr[0] ≠ 0; skipped where fr[0] = 0, so the other forces' numbers are unchanged).
    """
    n = p.shape[0]
    r2 = 0.0
    for i in range(n):
        r2 += p[i] * p[i]
    for i in range(n):
        s = (f[i] + tau * df[i] - k3[i] * p[i] * p[i] * p[i]
             - k3x[i] * (r2 - p[i] * p[i]) * p[i])
        for j in range(n):
            s -= K[i, j] * p[j] + D[i, j] * v[j]
        if fr[0, i] != 0.0:
            s -= fr[0, i] * np.tanh(v[i] / fr[1, i])
        a[i] = s


@njit(cache=True)
def cubic_kernel(K, D, B, k3, k3x, Kd, x0, u, dt, nsub, ymeas, use_meas, y,
                 foh=False, fr=None):  # pragma: no cover
    """p̈ + D ṗ + K p + k3∘p³ + k3x∘(|p|² − p²)∘p (+ friction) = B u, RK4 with ``nsub``
    sub-steps; ``fr`` (2, m): Coulomb friction sizes and smoothing velocities (_accel).

    The input is held over each sample (``foh=False``) or linear from u[k] to u[k+1]
    (``foh=True``, the same intersample behaviour as the linear FOH discretisation).
    Output y[k] = p[k]. With ``use_meas`` the innovation correction ``Kd (y_meas - p)`` is added
    to the state after each sample (one-step-ahead predictor); otherwise it is a simulation.
    """
    n = u.shape[0]
    m = K.shape[0]
    nu = B.shape[1]
    if fr is None:
        fr = np.zeros((2, m))
    p = x0[:m].copy()
    v = x0[m:].copy()
    f = np.empty(m)
    df = np.zeros(m)
    e = np.empty(m)
    a1 = np.empty(m)
    a2 = np.empty(m)
    a3 = np.empty(m)
    a4 = np.empty(m)
    pt = np.empty(m)
    k2p = np.empty(m)
    k3p = np.empty(m)
    k4p = np.empty(m)
    h = dt / nsub
    for k in range(n):
        for i in range(m):
            y[k, i] = p[i]
            e[i] = ymeas[k, i] - p[i] if use_meas else 0.0
        kn = k + 1 if k + 1 < n else k
        for i in range(m):
            s = 0.0
            s1 = 0.0
            for j in range(nu):
                s += B[i, j] * u[k, j]
                s1 += B[i, j] * u[kn, j]
            f[i] = s
            if foh:
                df[i] = s1 - s
        for q in range(nsub):
            t0 = q / nsub
            th = (q + 0.5) / nsub
            t1 = (q + 1.0) / nsub
            _accel(K, D, k3, k3x, fr, p, v, f, df, t0, a1)
            for i in range(m):
                k2p[i] = v[i] + 0.5 * h * a1[i]
                pt[i] = p[i] + 0.5 * h * v[i]
            _accel(K, D, k3, k3x, fr, pt, k2p, f, df, th, a2)
            for i in range(m):
                k3p[i] = v[i] + 0.5 * h * a2[i]
                pt[i] = p[i] + 0.5 * h * k2p[i]
            _accel(K, D, k3, k3x, fr, pt, k3p, f, df, th, a3)
            for i in range(m):
                k4p[i] = v[i] + h * a3[i]
                pt[i] = p[i] + h * k3p[i]
            _accel(K, D, k3, k3x, fr, pt, k4p, f, df, t1, a4)
            for i in range(m):
                p[i] += h / 6.0 * (v[i] + 2.0 * k2p[i] + 2.0 * k3p[i] + k4p[i])
                v[i] += h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i])
        if use_meas:
            for i in range(m):
                s1 = 0.0
                s2 = 0.0
                for j in range(m):
                    s1 += Kd[i, j] * e[j]
                    s2 += Kd[m + i, j] * e[j]
                p[i] += s1
                v[i] += s2


@njit(cache=True)
def expm_kernel(M):  # pragma: no cover - compiled
    """Matrix exponential by scaling and squaring with an 18-term Taylor series.

    Accurate to round-off for the small matrices (‖M‖ scaled below 0.5) used here; much
    cheaper than scipy's general routine for 4x4..10x10 matrices called thousands of times.
    """
    n = M.shape[0]
    nrm = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += abs(M[i, j])
        if s > nrm:
            nrm = s
    sq = 0
    while nrm > 0.5:
        nrm *= 0.5
        sq += 1
    X = M / (2.0 ** sq)
    E = np.eye(n)
    T = np.eye(n)
    for k in range(1, 19):
        T = (T @ X) / k
        E += T
    for _ in range(sq):
        E = E @ E
    return E
