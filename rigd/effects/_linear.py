"""Continuous linear blocks of the effects (:meth:`rigd.effects.base.Effect.linear`): what a
linear design model carries of an effect, as python-control state space (time in s).

An *input* block acts on each input before the model (``G · diag(L_j)``), an *output* block
is added in parallel (``G + P``), as the composition (rigd.effects.compose) runs their blocks.
"""

from __future__ import annotations

import math

import numpy as np

#: Padé order of a transport delay: enough for its phase up to 0.96 of the Nyquist frequency
#: (ω d/fs ≤ 0.96 π for d samples) within the cap
PADE_MIN, PADE_MAX = 2, 6


def _ss(A, B, C, D):
    import control

    return control.ss(np.atleast_2d(A), np.atleast_2d(B), np.atleast_2d(C), np.atleast_2d(D))


def pade_order(delay_samples: float) -> int:
    """Padé order for a delay of ``delay_samples`` (see :data:`PADE_MIN`)."""
    return int(min(PADE_MAX, max(PADE_MIN, math.ceil(0.96 * math.pi * delay_samples))))


def delay_block(tau_s: float, order: int):
    """e^{−s τ} as an ``order``-th order Padé approximant, realised at τ = 1 and scaled
    (A/τ, B/τ: well conditioned for a sub-millisecond τ); τ ≤ 0: a unit gain."""
    import control

    if tau_s <= 0:
        return _ss(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.0]])
    num, den = control.pade(1.0, order)
    P = control.ss(control.tf(num, den))
    return _ss(np.asarray(P.A) / tau_s, np.asarray(P.B) / tau_s, P.C, P.D)


def lag_block(taus_s) -> object:
    """∏ 1/(τ s + 1) over the positive ``taus_s`` (none: a unit gain)."""
    import control

    out = _ss(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.0]])
    for t in taus_s:
        if t > 0:
            out = control.ss(-1.0 / t, 1.0 / t, 1.0, 0.0) * out
    return out


def series_inputs(G, blocks):
    """``G · diag(blocks)``: block j (SISO) on input j of ``G``."""
    import control

    if len(blocks) != G.ninputs:
        raise ValueError(f"{len(blocks)} input blocks for a model of {G.ninputs} inputs")
    return G * control.append(*blocks)


def parallel(G, A, B, C):
    """``G + (A, B, C, 0)``: a linear path from the inputs to the outputs beside ``G``."""
    return G + _ss(A, B, C, np.zeros((G.noutputs, G.ninputs)))


def mechanical_shift(G, dK: np.ndarray, dD: np.ndarray):
    """``G`` of p̈ + D ṗ + K p = B u in states [p, ṗ] (C = [I 0]) with K + dK, D + dD; None
    when ``G`` is not in that form."""
    n = dK.shape[0]
    A, C = np.asarray(G.A, float), np.asarray(G.C, float)
    if A.shape != (2 * n, 2 * n) or C.shape != (n, 2 * n) \
            or not np.allclose(C, np.hstack([np.eye(n), np.zeros((n, n))])) \
            or not np.allclose(A[:n], np.hstack([np.zeros((n, n)), np.eye(n)])):
        return None
    A = A.copy()
    A[n:, :n] -= dK
    A[n:, n:] -= dD
    return _ss(A, G.B, C, G.D)
