"""Compiled simulators and one-step-ahead predictors for mechanical grey-box models.

All loops run in numba (``cache=True``); nothing here allocates per sample.

Linear models are discretised exactly (zero-order hold on the input, :func:`rigd.lti.zoh`) and
run by :func:`lsim_kernel` (simulation, output error) or :func:`predict_kernel` (one-step-ahead
predictor in innovation form). Models with a cubic stiffness (nonlinear) are integrated by a
fixed-step Runge-Kutta 4 with ``nsub`` sub-steps per sample (:func:`cubic_kernel`, input held
or linear between samples like the linear path), which can
also apply the innovation correction so the same kernel predicts.

The state-level effects' feedback (:class:`rigd.ident.feedback.MechanicalFeedback`: ΔK, ΔD, ΔB,
cubic stiffness, friction) enters :func:`simulate_mechanical` and :func:`predict_mechanical`;
everything else an effect does happens around the base (rigd.effects.compose). Parallel
modes (:class:`ExtraMode`, the order search's) are simulated by :func:`parallel_modes`.

The compiled kernels live in :mod:`rigd.ident.sim_kernels`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigd.ident import block_kernels as BK
from rigd.ident.feedback import MechanicalFeedback
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


def parallel_modes(modes: list[ExtraMode], u: np.ndarray, dt: float,
                   hold: str) -> np.ndarray | None:
    """Summed output (n, ny) of parallel ``modes`` driven by ``u`` (n, nu) (None: no mode),
    each discretised exactly with the input ``hold``."""
    out = None
    for m in modes:
        A = np.array([[0.0, 1.0], [-m.wn ** 2, -2 * m.zeta * m.wn]])
        Bm = np.zeros((2, u.shape[1]))
        Bm[1] = m.b
        Ad, Bd, ue = _discrete(A, Bm, dt, hold, u)
        z = np.empty((u.shape[0], 1))
        lsim_kernel(Ad, Bd, np.array([[1.0, 0.0]]), np.zeros(2), ue, z)
        contrib = z * np.asarray(m.c, float)[None, :]
        out = contrib if out is None else out + contrib
    return out


def _nonlinear(fb: MechanicalFeedback | None) -> bool:
    """True if ``fb`` has a cubic or friction term (RK4 path)."""
    if fb is None:
        return False
    return any(k is not None and np.any(np.asarray(k) != 0) for k in (fb.k3, fb.k3_cross)) or (
        fb.friction is not None and bool(np.any(np.asarray(fb.friction)[0] != 0)))


def _friction_terms(fb: MechanicalFeedback | None, m: int, dt: float,
                    nsub: int) -> tuple[np.ndarray, int]:
    """(friction (2, m) for the kernel, RK4 sub-steps): more sub-steps where the smoothed
    sign is steep (its slope F/v_ε times the sub-step kept below 1, at most 64)."""
    if fb is None or fb.friction is None:
        return np.zeros((2, m)), int(nsub)
    fr = np.ascontiguousarray(fb.friction, dtype=float).reshape(2, m).copy()
    fr[1] = np.where(fr[0] != 0, np.maximum(np.abs(fr[1]), 1e-300), 1.0)
    slope = float(np.max(np.abs(fr[0]) / fr[1]))
    need = int(np.ceil(slope * dt)) if np.isfinite(slope) else 64
    return fr, int(min(max(int(nsub), need), 64))


def _cubic(fb: MechanicalFeedback | None, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(k3, k3_cross) as float arrays of length m (zeros where unset)."""
    return tuple(np.zeros(m) if k is None else np.ascontiguousarray(k, dtype=float)
                 for k in ((None, None) if fb is None else (fb.k3, fb.k3_cross)))


def _matrices(K, D, B, fb: MechanicalFeedback | None):
    if fb is None:
        return K, D, B
    K = K if fb.dK is None else K + fb.dK
    D = D if fb.dD is None else D + fb.dD
    B = B if fb.dB is None else B + fb.dB
    return K, D, B


def simulate_mechanical(K, D, B, x0, u, fs, feedback: MechanicalFeedback | None = None,
                        hold: str = "zoh", nsub: int = 2) -> np.ndarray:
    """Simulated output p (n, ny) of p̈ + D ṗ + K p (+ φ(p, ṗ)) = B u from state ``x0``.

    Parameters
    ----------
    K, D : ndarray (m, m)
        Stiffness and damping normalised by the mass (1/s², 1/s).
    B : ndarray (m, nu)
        Input gain normalised by the mass (output unit / s² per input unit).
    x0 : ndarray (2m,)
        Initial [p, ṗ].
    u : ndarray (n, nu)
        Inputs.
    fs : float
        Sample rate, Hz.
    feedback : MechanicalFeedback, optional
        The state-level effects' feedback (rigd.ident.feedback): ΔK, ΔD, ΔB folded in; a
        cubic or friction term integrates by RK4 with ``nsub`` sub-steps (more where the
        friction's smoothed sign is steep).
    hold : {"zoh", "foh"}
        Input between samples: held, or linear (the linear and the RK4 path alike).
    """
    K, D, B = _matrices(np.asarray(K, float), np.asarray(D, float), np.asarray(B, float),
                        feedback)
    u = np.ascontiguousarray(u, dtype=float)
    m = K.shape[0]
    y = np.empty((u.shape[0], m))
    x0 = np.ascontiguousarray(x0, dtype=float)
    if _nonlinear(feedback):
        k3, k3x = _cubic(feedback, m)
        fr, nsub = _friction_terms(feedback, m, 1.0 / fs, nsub)
        cubic_kernel(K, D, B, k3, k3x, np.zeros((2 * m, m)), x0, u,
                     1.0 / fs, nsub, y, False, y, hold == "foh", fr)
    else:
        A, Bc, C = mechanical_abc(K, D, B)
        Ad, Bd, ue = _discrete(A, Bc, 1.0 / fs, hold, u)
        lsim_kernel(Ad, Bd, C, x0, ue, y)
    return y


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


def predict_mechanical(K, D, B, Bdist, x0, u, y, fs,
                       feedback: MechanicalFeedback | None = None, hold: str = "zoh",
                       nsub: int = 2, add: np.ndarray | None = None):
    """One-step-ahead prediction ŷ (n, ny) of Eq. 5 given measured ``y`` (n, ny).

    The disturbance d(t) enters the output and, through B_d, the states; its discretised
    gain is the innovation gain Kd. ``feedback``, ``hold``, ``nsub`` as
    :func:`simulate_mechanical`; ``add`` (n, ny): a known output added to the model's (output
    offsets, parallel modes), taken off the measurement first. Returns ``None`` if the
    predictor is unstable (spectral radius of Ad - Kd C >= 1), which the fit treats as a bad
    parameter set.
    """
    K, D, B = _matrices(np.asarray(K, float), np.asarray(D, float), np.asarray(B, float),
                        feedback)
    u = np.ascontiguousarray(u, dtype=float)
    m = K.shape[0]
    Ad, Bd, Kd, C, ue = predictor_gain(K, D, B, np.asarray(Bdist, float), fs, hold, u)
    if np.max(np.abs(np.linalg.eigvals(Ad - Kd @ C))) >= 1.0:
        return None
    ym = np.ascontiguousarray(y if add is None else y - add)
    yhat = np.empty((u.shape[0], m))
    x0 = np.ascontiguousarray(x0, dtype=float)
    if _nonlinear(feedback):
        k3, k3x = _cubic(feedback, m)
        fr, nsub = _friction_terms(feedback, m, 1.0 / fs, nsub)
        cubic_kernel(K, D, B, k3, k3x, Kd, x0, u, 1.0 / fs,
                     nsub, ym, True, yhat, hold == "foh", fr)
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


def _linear_discrete(lp, u, fs):
    """(delayed inputs uu, Ad, Bd, u_eff, blocks) of a linear part: its per-input delays as
    input shifts (:func:`shift_inputs`) and A, B discretised exactly with its hold — block by
    block when A is block-diagonal (real-block modal form, :mod:`rigd.ident.block_kernels`;
    ``blocks`` = (starts, count)), else whole (:func:`_discrete`; ``blocks`` None)."""
    uu = np.ascontiguousarray(shift_inputs(np.ascontiguousarray(u, dtype=float), lp.delays))
    A = np.asarray(lp.A, float)
    blk = BK.blocks(A) if np.all(np.isfinite(A)) else None
    if blk is not None:
        Ad, Bd, ue = BK.discrete(A, lp.B, 1.0 / fs, lp.hold, blk[0], blk[1], uu)
        return uu, Ad, Bd, ue, blk
    Ad, Bd, ue = _discrete(A, np.asarray(lp.B, float), 1.0 / fs, lp.hold, uu)
    return uu, Ad, Bd, ue, None


def simulate_linear(lp, x0, u, fs) -> np.ndarray:
    """Simulated output (n, ny) of a :class:`rigd.ident.model.LinearPart` from state ``x0``.

    A, B are discretised exactly with the part's hold (:func:`rigd.lti.zoh`/:func:`foh`;
    block by block for a real-block modal A, :func:`_linear_discrete`), the per-input delays
    are input shifts (:func:`shift_inputs`), then the compiled :func:`lsim_kernel` (or
    :func:`rigd.ident.block_kernels.block_kernel`) runs; ``y = C x + D u``.
    """
    uu, Ad, Bd, ue, blk = _linear_discrete(lp, u, fs)
    y = np.empty((uu.shape[0], lp.ny))
    C = np.ascontiguousarray(lp.C, dtype=float)
    x0 = np.ascontiguousarray(x0, dtype=float)
    if blk is not None:
        BK.block_kernel(Ad, blk[0], blk[1], Bd, np.zeros((lp.nx, 0)), C, x0, ue, y, y)
    else:
        lsim_kernel(Ad, Bd, C, x0, ue, y)
    if np.any(lp.D):
        y += uu @ np.asarray(lp.D, float).T
    return y


def predict_linear(lp, x0, u, y, fs) -> np.ndarray | None:
    """One-step-ahead prediction (n, ny) of a linear part with innovation gain ``lp.K``
    (discrete, nx × ny); ``None`` if the predictor is unstable (spectral radius of
    Ad − K C ≥ 1). Same discretisation and delays as :func:`simulate_linear`."""
    uu, Ad, Bd, ue, blk = _linear_discrete(lp, u, fs)
    C = np.ascontiguousarray(lp.C, dtype=float)
    Kd = (np.zeros((lp.nx, lp.ny)) if lp.K is None
          else np.ascontiguousarray(lp.K, dtype=float))
    if not np.all(np.isfinite(Ad)) or (lp.nx and np.max(np.abs(np.linalg.eigvals(
            Ad - Kd @ C)))) >= 1.0:
        return None
    direct = uu @ np.asarray(lp.D, float).T if np.any(lp.D) else None
    ym = np.asarray(y, float) if direct is None else np.asarray(y, float) - direct
    yhat = np.empty((uu.shape[0], lp.ny))
    x0, ym = np.ascontiguousarray(x0, dtype=float), np.ascontiguousarray(ym)
    if blk is not None:
        BK.block_kernel(Ad, blk[0], blk[1], Bd, Kd, C, x0, ue, ym, yhat)
    else:
        predict_kernel(Ad, Bd, Kd, C, x0, ue, ym, yhat)
    return yhat if direct is None else yhat + direct
