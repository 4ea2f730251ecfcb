"""Compiled simulators and one-step-ahead predictors for mechanical grey-box models.

All loops run in numba (``cache=True``); nothing here allocates per sample.

Linear models are discretised exactly (zero-order hold on the input, :func:`zoh`) and run by
:func:`lsim_kernel` (simulation, output error) or :func:`predict_kernel` (one-step-ahead
predictor in innovation form). Models with a cubic stiffness (nonlinear) are integrated by a
fixed-step Runge-Kutta 4 with ``nsub`` sub-steps per sample (:func:`cubic_kernel`, input held
or linear between samples like the linear path), which can
also apply the innovation correction so the same kernel predicts.

The :class:`Hooks` bundle carries the optional modifications that physical effects need
(input delay, input pre-transform, cubic stiffness, extra parallel modes, additive output,
additive changes of the K/D/B matrices); :func:`simulate_mechanical` and
:func:`predict_mechanical` apply them around the base model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

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


@njit(cache=True)
def _accel(K, D, k3, k3x, p, v, f, df, tau, a):  # pragma: no cover - compiled
    """Acceleration at force f + tau·df (df: force change over the sample, FOH).

    Cubic force on axis i: k3_i p_i³ + k3x_i (Σ_{j≠i} p_j²) p_i (k3x = k3: radial, |p|² p).
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
        a[i] = s


@njit(cache=True)
def cubic_kernel(K, D, B, k3, k3x, Kd, x0, u, dt, nsub, ymeas, use_meas, y,
                 foh=False):  # pragma: no cover
    """p̈ + D ṗ + K p + k3∘p³ + k3x∘(|p|² − p²)∘p = B u, RK4 with ``nsub`` sub-steps.

    The input is held over each sample (``foh=False``) or linear from u[k] to u[k+1]
    (``foh=True``, the same intersample behaviour as the linear FOH discretisation).
    Output y[k] = p[k]. With ``use_meas`` the innovation correction ``Kd (y_meas - p)`` is added
    to the state after each sample (one-step-ahead predictor); otherwise it is a simulation.
    """
    n = u.shape[0]
    m = K.shape[0]
    nu = B.shape[1]
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
            _accel(K, D, k3, k3x, p, v, f, df, t0, a1)
            for i in range(m):
                k2p[i] = v[i] + 0.5 * h * a1[i]
                pt[i] = p[i] + 0.5 * h * v[i]
            _accel(K, D, k3, k3x, pt, k2p, f, df, th, a2)
            for i in range(m):
                k3p[i] = v[i] + 0.5 * h * a2[i]
                pt[i] = p[i] + 0.5 * h * k2p[i]
            _accel(K, D, k3, k3x, pt, k3p, f, df, th, a3)
            for i in range(m):
                k4p[i] = v[i] + h * a3[i]
                pt[i] = p[i] + h * k3p[i]
            _accel(K, D, k3, k3x, pt, k4p, f, df, t1, a4)
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


# --------------------------------------------------------------------------------------
# Python helpers
# --------------------------------------------------------------------------------------
def zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation (Ad, Bd) of ẋ = A x + B u with period ``dt`` (s)."""
    nx, nb = A.shape[0], B.shape[1]
    M = np.zeros((nx + nb, nx + nb))
    M[:nx, :nx] = A * dt
    M[:nx, nx:] = B * dt
    if not np.all(np.isfinite(M)):
        E = np.full_like(M, np.nan)
    else:
        E = expm_kernel(M)
    return np.ascontiguousarray(E[:nx, :nx]), np.ascontiguousarray(E[:nx, nx:])


def foh(A: np.ndarray, B: np.ndarray, dt: float):
    """First-order-hold (triangle) discretisation: input linear between samples.

    x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1]; returns (Ad, B0, B1).
    """
    nx, nb = A.shape[0], B.shape[1]
    M = np.zeros((nx + 2 * nb, nx + 2 * nb))
    M[:nx, :nx] = A * dt
    M[:nx, nx:nx + nb] = B * dt
    M[nx:nx + nb, nx + nb:] = np.eye(nb)
    E = expm_kernel(M) if np.all(np.isfinite(M)) else np.full_like(M, np.nan)
    G1, G2 = E[:nx, nx:nx + nb], E[:nx, nx + nb:]
    return (np.ascontiguousarray(E[:nx, :nx]), np.ascontiguousarray(G1 - G2),
            np.ascontiguousarray(G2))


def _discrete(A, Bc, dt, hold, u):
    """(Ad, Bd, u_eff): ZOH, or FOH written as a ZOH system on inputs [u[k], u[k+1]]."""
    if hold == "foh":
        Ad, B0, B1 = foh(A, Bc, dt)
        un = np.empty_like(u)
        un[:-1] = u[1:]
        un[-1:] = u[-1:]
        return Ad, np.ascontiguousarray(np.hstack([B0, B1])), np.ascontiguousarray(
            np.hstack([u, un]))
    Ad, Bd = zoh(A, Bc, dt)
    return Ad, Bd, u


def mechanical_abc(K, D, B):
    """State-space matrices of p̈ + D ṗ + K p = B u with x = [p, ṗ] (Eq. 6)."""
    n = K.shape[0]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -K
    A[n:, n:] = -D
    Bc = np.zeros((2 * n, B.shape[1]))
    Bc[n:, :] = B
    C = np.zeros((n, 2 * n))
    C[:, :n] = np.eye(n)
    return A, Bc, C


@dataclass
class ExtraMode:
    """A parallel second-order mode z̈ + 2ζω ż + ω² z = b·u adding ``c z`` to the outputs.

    Attributes: ``wn`` (rad/s), ``zeta`` (-), ``b`` (nu,), ``c`` (ny,).
    """

    wn: float
    zeta: float
    b: np.ndarray
    c: np.ndarray


@dataclass
class Hooks:
    """Optional modifications of a mechanical model, set by effects (see ``docs/identify.md``).

    Attributes
    ----------
    delay : int
        Input delay, samples (u[k - delay] drives the model; zero before the start).
    input_transform : callable (n, nu) -> (n, nu), optional
        Applied to the (delayed) inputs first (hysteresis, valve dynamics, creep ...).
    k3 : ndarray (ny,), optional
        Per-axis cubic stiffness, force k3_i p_i³ (acceleration per output unit cubed);
        nonlinear -> RK4 integration.
    k3_cross : ndarray (ny,), optional
        Cubic stiffness of axis i from the other axes' amplitude, force k3_cross_i ·
        (Σ_{j≠i} p_j²) p_i (k3_cross = k3: radial film stiffening k3 |p|² p).
    extra_modes : list of ExtraMode
        Parallel modes added to the output.
    output_add : ndarray (n, ny), optional
        Added to the simulated output (run-out harmonics ...).
    dK, dD, dB : ndarray, optional
        Added to K, D, B (cross-coupling terms of a decoupled model ...).
    nsub : int
        RK4 sub-steps per sample for the nonlinear path.
    hold : {"zoh", "foh"}
        Input between samples: held (commanded signals) or linear (measured, smooth
        signals). Set by the structure; applies to the linear and the cubic (RK4) path
        and to the extra modes alike.
    """

    delay: int = 0
    input_transform: Callable[[np.ndarray], np.ndarray] | None = None
    k3: np.ndarray | None = None
    k3_cross: np.ndarray | None = None
    extra_modes: list[ExtraMode] = field(default_factory=list)
    output_add: np.ndarray | None = None
    dK: np.ndarray | None = None
    dD: np.ndarray | None = None
    dB: np.ndarray | None = None
    nsub: int = 2
    hold: str = "zoh"

    @property
    def nonlinear(self) -> bool:
        """True if a cubic term is set (RK4 path)."""
        return any(k is not None and np.any(np.asarray(k) != 0)
                   for k in (self.k3, self.k3_cross))

    def cubic(self, m: int) -> tuple[np.ndarray, np.ndarray]:
        """(k3, k3_cross) as float arrays of length m (zeros where unset)."""
        return tuple(np.zeros(m) if k is None else np.ascontiguousarray(k, dtype=float)
                     for k in (self.k3, self.k3_cross))

    def transform_input(self, u: np.ndarray) -> np.ndarray:
        if self.delay > 0:
            ud = np.zeros_like(u)
            if self.delay < len(u):
                ud[self.delay:] = u[:-self.delay]
            u = ud
        if self.input_transform is not None:
            u = np.ascontiguousarray(self.input_transform(u), dtype=float)
        return u

    def additive_output(self, u: np.ndarray, dt: float, ny: int) -> np.ndarray | None:
        """Output of the extra modes plus ``output_add`` (None if there is neither)."""
        out = None if self.output_add is None else np.array(self.output_add, float)
        for m in self.extra_modes:
            A = np.array([[0.0, 1.0], [-m.wn ** 2, -2 * m.zeta * m.wn]])
            Bm = np.zeros((2, u.shape[1]))
            Bm[1] = m.b
            Ad, Bd, ue = _discrete(A, Bm, dt, self.hold, u)
            z = np.empty((u.shape[0], 1))
            lsim_kernel(Ad, Bd, np.array([[1.0, 0.0]]), np.zeros(2), ue, z)
            contrib = z * np.asarray(m.c, float)[None, :]
            out = contrib if out is None else out + contrib
        return out


def _matrices(K, D, B, hooks: Hooks):
    K = K if hooks.dK is None else K + hooks.dK
    D = D if hooks.dD is None else D + hooks.dD
    B = B if hooks.dB is None else B + hooks.dB
    return K, D, B


def simulate_mechanical(K, D, B, x0, u, fs, hooks: Hooks | None = None) -> np.ndarray:
    """Simulated output p (n, ny) of p̈ + D ṗ + K p (+ k3 p³) = B u from state ``x0``.

    Parameters
    ----------
    K, D : ndarray (m, m)
        Stiffness and damping normalised by the mass (1/s², 1/s).
    B : ndarray (m, nu)
        Input gain normalised by the mass (output unit / s² per input unit).
    x0 : ndarray (2m,)
        Initial [p, ṗ].
    u : ndarray (n, nu)
        Inputs, held over each sample (ZOH).
    fs : float
        Sample rate, Hz.
    hooks : Hooks, optional
        Effect hooks (delay, cubic stiffness, extra modes, ...).
    """
    hooks = hooks or Hooks()
    K, D, B = _matrices(np.asarray(K, float), np.asarray(D, float), np.asarray(B, float), hooks)
    u = np.ascontiguousarray(u, dtype=float)
    uu = hooks.transform_input(u)
    m = K.shape[0]
    y = np.empty((u.shape[0], m))
    x0 = np.ascontiguousarray(x0, dtype=float)
    if hooks.nonlinear:
        k3, k3x = hooks.cubic(m)
        cubic_kernel(K, D, B, k3, k3x, np.zeros((2 * m, m)), x0, uu,
                     1.0 / fs, int(hooks.nsub), y, False, y, hooks.hold == "foh")
    else:
        A, Bc, C = mechanical_abc(K, D, B)
        Ad, Bd, ue = _discrete(A, Bc, 1.0 / fs, hooks.hold, uu)
        lsim_kernel(Ad, Bd, C, x0, ue, y)
    add = hooks.additive_output(uu, 1.0 / fs, m)
    return y if add is None else y + add


def predictor_gain(K, D, B, Bdist, fs, hold="zoh", u=None):
    """Discrete (Ad, Bd, Kd, C, u_eff) of Eq. 5: d enters the states through 𝓑_d = [0; B_d].

    The disturbance is discretised with a zero-order hold (its gain is the innovation gain
    Kd); the input with ``hold`` (``u_eff`` is the input sequence the kernel needs).
    """
    A, Bc, C = mechanical_abc(K, D, B)
    m = K.shape[0]
    Bdc = np.zeros((2 * m, m))
    Bdc[m:, :] = Bdist
    Ad, Kd = zoh(A, Bdc, 1.0 / fs)
    if u is None:
        _, Bd = zoh(A, Bc, 1.0 / fs)
        return Ad, Bd, Kd, C, None
    _, Bd, ue = _discrete(A, Bc, 1.0 / fs, hold, u)
    return Ad, Bd, Kd, C, ue


def predict_mechanical(K, D, B, Bdist, x0, u, y, fs, hooks: Hooks | None = None):
    """One-step-ahead prediction ŷ (n, ny) of Eq. 5 given measured ``y`` (n, ny).

    The disturbance d(t) enters the output and, through B_d, the states; its discretised
    gain is the innovation gain Kd. Returns ``None`` if the predictor is unstable
    (spectral radius of Ad - Kd C >= 1), which the fit treats as a bad parameter set.
    """
    hooks = hooks or Hooks()
    K, D, B = _matrices(np.asarray(K, float), np.asarray(D, float), np.asarray(B, float), hooks)
    u = np.ascontiguousarray(u, dtype=float)
    uu = hooks.transform_input(u)
    m = K.shape[0]
    Ad, Bd, Kd, C, ue = predictor_gain(K, D, B, np.asarray(Bdist, float), fs, hooks.hold, uu)
    if np.max(np.abs(np.linalg.eigvals(Ad - Kd @ C))) >= 1.0:
        return None
    add = hooks.additive_output(uu, 1.0 / fs, m)
    ym = np.ascontiguousarray(y if add is None else y - add)
    yhat = np.empty((u.shape[0], m))
    x0 = np.ascontiguousarray(x0, dtype=float)
    if hooks.nonlinear:
        k3, k3x = hooks.cubic(m)
        cubic_kernel(K, D, B, k3, k3x, Kd, x0, uu, 1.0 / fs,
                     int(hooks.nsub), ym, True, yhat, hooks.hold == "foh")
    else:
        predict_kernel(Ad, Bd, Kd, C, x0, ue, ym, yhat)
    return yhat if add is None else yhat + add
