"""Compiled simulators and one-step-ahead predictors for mechanical grey-box models.

All loops run in numba (``cache=True``); nothing here allocates per sample.

Linear models are discretised exactly (zero-order hold on the input, :func:`rigd.lti.zoh`) and
run by :func:`lsim_kernel` (simulation, output error) or :func:`predict_kernel` (one-step-ahead
predictor in innovation form). Models with a cubic stiffness (nonlinear) are integrated by a
fixed-step Runge-Kutta 4 with ``nsub`` sub-steps per sample (:func:`cubic_kernel`, input held
or linear between samples like the linear path), which can
also apply the innovation correction so the same kernel predicts.

The :class:`Hooks` bundle carries the optional modifications that physical effects need
(input delay, input pre-transform, cubic stiffness, extra parallel modes, additive output,
additive changes of the K/D/B matrices); :func:`simulate_mechanical` and
:func:`predict_mechanical` apply them around the base model.

The compiled kernels live in :mod:`rigd.ident.sim_kernels`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rigd.ident.sim_kernels import cubic_kernel, expm_kernel, lsim_kernel, predict_kernel
from rigd.lti import foh, zoh


# --------------------------------------------------------------------------------------
# Python helpers
# --------------------------------------------------------------------------------------
def _discrete(A, Bc, dt, hold, u):
    """(Ad, Bd, u_eff): ZOH, or FOH written as a ZOH system on inputs [u[k], u[k+1]]."""
    if hold == "foh":
        Ad, B0, B1 = foh(A, Bc, dt, expm=expm_kernel)
        un = np.empty_like(u)
        un[:-1] = u[1:]
        un[-1:] = u[-1:]
        return Ad, np.ascontiguousarray(np.hstack([B0, B1])), np.ascontiguousarray(
            np.hstack([u, un]))
    Ad, Bd = zoh(A, Bc, dt, expm=expm_kernel)
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
    friction : ndarray (2, ny), optional
        Per-axis dry (Coulomb) friction: force friction[0, i]·tanh(ṗ_i / friction[1, i])
        against the motion (acceleration units; smoothing velocity in output units/s);
        nonlinear -> RK4 integration.
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
    friction: np.ndarray | None = None
    nsub: int = 2
    hold: str = "zoh"

    @property
    def nonlinear(self) -> bool:
        """True if a cubic or friction term is set (RK4 path)."""
        return any(k is not None and np.any(np.asarray(k) != 0)
                   for k in (self.k3, self.k3_cross)) or (
            self.friction is not None and bool(np.any(np.asarray(self.friction)[0] != 0)))

    def friction_terms(self, m: int, dt: float) -> tuple[np.ndarray, int]:
        """(friction (2, m) for the kernel, RK4 sub-steps): more sub-steps where the smoothed
        sign is steep (its slope F/v_ε times the sub-step kept below 1, at most 64)."""
        if self.friction is None:
            return np.zeros((2, m)), int(self.nsub)
        fr = np.ascontiguousarray(self.friction, dtype=float).reshape(2, m).copy()
        fr[1] = np.where(fr[0] != 0, np.maximum(np.abs(fr[1]), 1e-300), 1.0)
        slope = float(np.max(np.abs(fr[0]) / fr[1]))
        need = int(np.ceil(slope * dt)) if np.isfinite(slope) else 64
        return fr, int(min(max(int(self.nsub), need), 64))

    def cubic(self, m: int) -> tuple[np.ndarray, np.ndarray]:
        """(k3, k3_cross) as float arrays of length m (zeros where unset)."""
        return tuple(np.zeros(m) if k is None else np.ascontiguousarray(k, dtype=float)
                     for k in (self.k3, self.k3_cross))

    def plus_output(self, add: np.ndarray) -> Hooks:
        """A copy with ``add`` added to :attr:`output_add` (the caller's hooks unchanged: they
        may be used for another simulation)."""
        return dataclasses.replace(
            self, output_add=add if self.output_add is None else self.output_add + add)

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
        fr, nsub = hooks.friction_terms(m, 1.0 / fs)
        cubic_kernel(K, D, B, k3, k3x, np.zeros((2 * m, m)), x0, uu,
                     1.0 / fs, nsub, y, False, y, hooks.hold == "foh", fr)
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
    Ad, Kd = zoh(A, Bdc, 1.0 / fs, expm=expm_kernel)
    if u is None:
        _, Bd = zoh(A, Bc, 1.0 / fs, expm=expm_kernel)
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
        fr, nsub = hooks.friction_terms(m, 1.0 / fs)
        cubic_kernel(K, D, B, k3, k3x, Kd, x0, uu, 1.0 / fs,
                     nsub, ym, True, yhat, hooks.hold == "foh", fr)
    else:
        predict_kernel(Ad, Bd, Kd, C, x0, ue, ym, yhat)
    return yhat if add is None else yhat + add


# --------------------------------------------------------------------------------------
# any linear part (rigd.ident.model.LinearPart): one kernel for every family
# --------------------------------------------------------------------------------------
def shift_inputs(u: np.ndarray, delays) -> np.ndarray:
    """u with column j delayed by ``delays[j]`` samples; before the start each column holds
    its first value (the record is taken to start at rest on its first input)."""
    d = np.asarray(delays, int)
    if not np.any(d):
        return u
    out = np.empty_like(u)
    n = u.shape[0]
    for j, dj in enumerate(d):
        dj = min(int(dj), n)
        out[:dj, j] = u[0, j]
        out[dj:, j] = u[:n - dj, j]
    return out


def _linear_inputs(lp, u: np.ndarray, hooks: Hooks | None) -> np.ndarray:
    u = np.ascontiguousarray(u, dtype=float)
    if hooks is not None:
        u = hooks.transform_input(u)
    return np.ascontiguousarray(shift_inputs(u, lp.delays))


def _hooks_unsupported(hooks: Hooks | None) -> bool:
    """True if ``hooks`` ask for a mechanical state-level change (cubic stiffness, K/D/B
    increments) that a general linear part cannot carry."""
    return hooks is not None and (hooks.nonlinear or any(
        h is not None for h in (hooks.dK, hooks.dD, hooks.dB)))


def simulate_linear(lp, x0, u, fs, hooks: Hooks | None = None) -> np.ndarray:
    """Simulated output (n, ny) of a :class:`rigd.ident.model.LinearPart` from state ``x0``.

    A, B are discretised exactly with the part's hold (:func:`rigd.lti.zoh`/:func:`foh`),
    the per-input delays are input shifts (:func:`shift_inputs`), then the compiled
    :func:`lsim_kernel` runs; ``y = C x + D u``. ``hooks`` (effects): input delay and
    transform, extra modes and additive output apply; a mechanical state-level change
    (cubic stiffness, dK/dD/dB) cannot be carried by a general linear part and gives NaN
    (the fit treats it as a failed simulation).
    """
    uu = _linear_inputs(lp, u, hooks)
    n, ny = uu.shape[0], lp.ny
    if _hooks_unsupported(hooks):
        return np.full((n, ny), np.nan)
    Ad, Bd, ue = _discrete(np.asarray(lp.A, float), np.asarray(lp.B, float), 1.0 / fs,
                           lp.hold, uu)
    y = np.empty((n, ny))
    lsim_kernel(Ad, Bd, np.ascontiguousarray(lp.C, dtype=float),
                np.ascontiguousarray(x0, dtype=float), ue, y)
    if np.any(lp.D):
        y += uu @ np.asarray(lp.D, float).T
    if hooks is not None:
        add = dataclasses.replace(hooks, hold=lp.hold).additive_output(uu, 1.0 / fs, ny)
        if add is not None:
            y += add
    return y


def predict_linear(lp, x0, u, y, fs, hooks: Hooks | None = None) -> np.ndarray | None:
    """One-step-ahead prediction (n, ny) of a linear part with innovation gain ``lp.K``
    (discrete, nx × ny); ``None`` if the predictor is unstable (spectral radius of
    Ad − K C ≥ 1). Same discretisation, delays and hooks as :func:`simulate_linear`."""
    uu = _linear_inputs(lp, u, hooks)
    n, ny = uu.shape[0], lp.ny
    if _hooks_unsupported(hooks):
        return None
    Ad, Bd, ue = _discrete(np.asarray(lp.A, float), np.asarray(lp.B, float), 1.0 / fs,
                           lp.hold, uu)
    C = np.ascontiguousarray(lp.C, dtype=float)
    Kd = np.zeros((lp.nx, ny)) if lp.K is None else np.ascontiguousarray(lp.K, dtype=float)
    if not np.all(np.isfinite(Ad)) or (lp.nx and np.max(np.abs(np.linalg.eigvals(
            Ad - Kd @ C)))) >= 1.0:
        return None
    add = None
    if hooks is not None:
        add = dataclasses.replace(hooks, hold=lp.hold).additive_output(uu, 1.0 / fs, ny)
    direct = uu @ np.asarray(lp.D, float).T if np.any(lp.D) else None
    ym = np.asarray(y, float)
    for part in (add, direct):
        if part is not None:
            ym = ym - part
    yhat = np.empty((n, ny))
    predict_kernel(Ad, Bd, Kd, C, np.ascontiguousarray(x0, dtype=float), ue,
                   np.ascontiguousarray(ym), yhat)
    for part in (add, direct):
        if part is not None:
            yhat += part
    return yhat
