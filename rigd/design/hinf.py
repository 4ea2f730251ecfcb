"""Mixed-sensitivity H∞ synthesis of K∞(s) (paper Sec. 5).

The generalized plant P has exogenous inputs w = [d_o, d_i] (output disturbance on p, µm;
input disturbance on the valve command, V, scaled by W_d), control input u = r (V), error
outputs z = [W_p p, W_u u] and measurement v = −p (the loop feeds −(p − p_eq)). With u = K v
the closed loop w → z is::

    d_o → z:  [W_p S,   −W_u K S]ᵀ              (the paper's N = [W_p S, W_u K S]ᵀ)
    d_i → z:  [W_p S G W_d, −W_u K S G W_d]ᵀ    (only when W_d > 0)

so γ = ‖F_l(P, K)‖∞ ≥ ‖N‖∞, and S = S_o = (I + G_p K)⁻¹ as Eq. 11 (negative feedback).

With a high-pass H_hp = (s/(s+ω_h))^m (:class:`rigd.design.weights.HighPass`) the synthesis
runs on the augmented plant G_p·H_hp and returns K̃; the deployed controller is
K∞ = H_hp·K̃, which has an m-fold zero at s = 0 whatever the synthesis does: no action at DC
and little below ω_h (the paper's "controller not active at low frequencies", Fig. 5). The
weights W_u and W_p see K̃ and the augmented loop (G_p H_hp K̃ = G_p K∞, so S is the same).
Synthesis uses SLICOT SB10AD through slycot (γ-iteration, as python-control ``hinfsyn``). The
problem is solved in a frequency-scaled time unit (ω/ω_s) so that the Riccati equations are
well conditioned, and the controller is scaled back.

**A stable controller.** The central controller at the optimal γ can be unstable *by itself*
while the closed loop is stable: near the optimum it places poles at (mirror images of) the
plant's lightly damped right-half-plane zeros. A delay in series with a base model and a
structural mode in parallel (the improved model of the demo: Padé of 1.27 samples, extra
mode at 330 Hz) puts such a zero pair at 3.7 ± 286j Hz — the LHP pair −11.6 ± 283j Hz of
base + mode moved across the axis by the delay's phase — and the optimal K̃ then has a pole
pair at +1.9 ± 295j Hz. The loop loads no unstable K∞(z) (:mod:`rigd.controller`: it runs
while its output is not applied), and truncation keeps the unstable part. So when the
optimal K̃ is unstable, the central controller is recomputed at the relaxed levels
γ_opt·:data:`RELAX_FACTORS` (SB10AD without iteration, ``job=4``) and the first one that is
stable with a stable closed loop is kept; γ is then that level, ``gamma_optimal`` the
optimum (on the demo's improved model: 1.68 → 2.02 at 1.2×).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rigd.design.robustness import is_stable
from rigd.design.weights import HighPass, Weights, highpass_ss, three_level
from rigd.errors import InputError

#: Frequency scale of the synthesis (rad/s): 2π·100 Hz, the bearing modes' neighbourhood.
OMEGA_SCALE = 2.0 * np.pi * 100.0
#: Levels γ/γ_opt tried, in order, when the optimal central controller is not stable itself.
RELAX_FACTORS = (1.05, 1.1, 1.2, 1.3, 1.5, 2.0, 3.0)


@dataclass
class HinfResult:
    """Full-order H∞ controller and what the synthesis reports.

    Attributes
    ----------
    K : control.StateSpace
        Continuous K∞(s), e = −p (µm) → r (V), negative-feedback convention.
    gamma : float
        Achieved ‖F_l(P, K)‖∞ (γ < 1: all weighted specifications met).
    closed_loop_stable : bool
        Closed loop (G_p, K) stable (continuous).
    """

    K: object
    gamma: float
    closed_loop_stable: bool
    K_tilde: object = None      # K̃ designed on G_p·H_hp (K = H_hp·K̃); K itself without H_hp
    H: object = None            # H_hp (2×2), None without a high-pass
    conditioning: dict | None = None   # what rigd.design.condition did to the plant
    gamma_optimal: float = float("nan")   # optimal γ (= gamma unless relaxed for a stable K̃)
    relaxed: list = field(default_factory=list)   # [{factor, gamma, controller_stable}] tried


def _freq_scale(sys, w: float):
    import control

    return control.ss(sys.A / w, sys.B / w, sys.C, sys.D)


def generalized_plant(G, Wp, Wu, wd: float):
    """Generalized plant P for :func:`synthesize` (see module docstring).

    Parameters
    ----------
    G : control.StateSpace
        Plant G_p, 2 inputs r (V) → 2 outputs p (µm), strictly proper.
    Wp, Wu : control.StateSpace
        2×2 weights on p (S) and on u (K S).
    wd : float
        Input-disturbance weight (0: no input-disturbance channel).

    Returns
    -------
    control.StateSpace
        Inputs [w (2 or 4), u (2)], outputs [z (4), v (2)].
    """
    import control

    ny, nu = G.noutputs, G.ninputs
    if np.any(np.abs(G.D) > 0):
        raise InputError("plant model must be strictly proper (D = 0) for the H∞ design",
                         "model")
    Ag, Bg, Cg = G.A, G.B, G.C
    Ap, Bp, Cp, Dp = Wp.A, Wp.B, Wp.C, Wp.D
    Au, Bu, Cu, Du = Wu.A, Wu.B, Wu.C, Wu.D
    ng, np_, nw = Ag.shape[0], Ap.shape[0], Au.shape[0]
    Z = np.zeros
    A = np.block([[Ag, Z((ng, np_)), Z((ng, nw))],
                  [Bp @ Cg, Ap, Z((np_, nw))],
                  [Z((nw, ng)), Z((nw, np_)), Au]])
    Bo = np.vstack([Z((ng, ny)), Bp, Z((nw, ny))])          # output disturbance d_o
    B2 = np.vstack([Bg, Z((np_, nu)), Bu])                  # control u
    C1 = np.block([[Dp @ Cg, Cp, Z((ny, nw))], [Z((nu, ng)), Z((nu, np_)), Cu]])
    C2 = np.hstack([-Cg, Z((ny, np_)), Z((ny, nw))])
    D1o = np.vstack([Dp, Z((nu, ny))])
    D12 = np.vstack([Z((ny, nu)), Du])
    D2o = -np.eye(ny)
    if wd > 0:
        Bi = np.vstack([Bg * wd, Z((np_, nu)), Z((nw, nu))])  # input disturbance d_i
        B1 = np.hstack([Bo, Bi])
        D11 = np.hstack([D1o, Z((ny + nu, nu))])
        D21 = np.hstack([D2o, Z((ny, nu))])
    else:
        B1, D11, D21 = Bo, D1o, D2o
    return control.ss(A, np.hstack([B1, B2]), np.vstack([C1, C2]),
                      np.block([[D11, D12], [D21, np.zeros((ny, nu))]]))


def synthesize(G, weights: Weights, highpass: HighPass | None = None) -> HinfResult:
    """Mixed-sensitivity H∞ controller for plant ``G`` with ``weights`` (γ-iteration by SLICOT).

    With ``highpass`` (order m > 0) the synthesis runs on G·H_hp and K = H_hp·K̃ is returned.
    An optimal K̃ that is unstable itself is replaced by the first stable central controller
    at a relaxed level γ_opt·:data:`RELAX_FACTORS` (module docstring; ``relaxed`` lists the
    levels tried; none stable: the optimal one is returned and the caller's checks say so).

    Raises
    ------
    InputError
        When the problem has no solution (e.g. weights that make it infeasible or ill-posed).
    """
    ny, nu = G.noutputs, G.ninputs
    if (ny, nu) != (2, 2):
        raise InputError(f"plant must be 2x2 (r_x, r_y -> e_x, e_y), got {ny}x{nu}", "model")
    Wp = three_level(weights.W_p, ny)
    Wu = three_level(weights.W_u, nu)
    H = highpass_ss(highpass, nu) if highpass is not None and highpass.order > 0 else None
    Ga = G * H if H is not None else G
    w = OMEGA_SCALE
    P = generalized_plant(_freq_scale(Ga, w), _freq_scale(Wp, w), _freq_scale(Wu, w), weights.W_d)
    gamma, Ks = _sb10ad(P, ny, nu)
    g_opt, tried, loop_stable = gamma, [], None
    Kt = _unscale(Ks, w)
    if not _stable(Ks.A):
        for f in RELAX_FACTORS:
            try:
                g, Kf = _sb10ad(P, ny, nu, g_opt * f)
            except InputError:
                continue
            Kft = _unscale(Kf, w)
            ok = _stable(Kf.A) and is_stable(G, H * Kft if H is not None else Kft)
            tried.append({"factor": f, "gamma": g, "controller_stable": ok})
            if ok:   # its loop was checked just now: not again below
                gamma, Kt, loop_stable = g, Kft, True
                break
    K = H * Kt if H is not None else Kt
    if loop_stable is None:
        loop_stable = is_stable(G, K)
    return HinfResult(K=K, gamma=float(gamma), closed_loop_stable=loop_stable,
                      K_tilde=Kt, H=H, gamma_optimal=float(g_opt), relaxed=tried)


def _stable(A) -> bool:
    """All eigenvalues of the continuous ``A`` in the open left half-plane."""
    A = np.asarray(A, float)
    return bool(A.size == 0 or np.max(np.linalg.eigvals(A).real) < 0.0)


def _unscale(K, w: float):
    import control

    return control.ss(np.asarray(K.A) * w, np.asarray(K.B) * w, K.C, K.D)


def _sb10ad(P, ny: int, nu: int, gamma: float | None = None):
    """(γ, K) of SLICOT SB10AD on the generalized plant ``P``: the optimal γ by its
    iteration (``gamma`` None), else the central controller at the level ``gamma``."""
    import control
    from slycot import sb10ad

    n, m, p = P.A.shape[0], P.B.shape[1], P.C.shape[0]
    args = (n, m, p, nu, ny, 1e100 if gamma is None else float(gamma), P.A, P.B, P.C, P.D)
    try:
        out = sb10ad(*args) if gamma is None else sb10ad(*args, job=4)
    except Exception as exc:  # slycot raises its own error types with the SLICOT info code
        raise InputError(f"H∞ synthesis failed ({type(exc).__name__}: {exc}); "
                         "check the weights and the plant model", "design") from None
    return float(out[0]), control.ss(out[1], out[2], out[3], out[4])
