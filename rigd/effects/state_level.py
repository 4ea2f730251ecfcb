"""A mechanical model with a cubic force, simulated sample by sample (signature regressors).

A mechanical structure (paper Eq. 5-6: x = [p, ṗ], A = [[0, I], [-K, -D]], B = [[0], [B]],
C = [I, 0]) that exposes ``continuous(theta) -> (A, B, C, D, x0)`` can be extended at state
level:

* linear feedback of positions and velocities into the force input, u' = u + Kc p + Dc ṗ
  (cross-coupled stiffness / gyroscopic damping, Eq. 4's Ω G term), which stays linear:
  A' = A + B [Kc, Dc] [C; C A];
* a cubic force, u' = u − K3 p³ (film stiffening, Duffing), simulated by a compiled
  sample-by-sample kernel with the zero-order-hold discretisation of (A', B).

:func:`simulate_state` is what :meth:`rigd.effects.context.Context.through_force` uses for the
response to a force on one axis; the fitted models carry their state-level effects through
the composition (rigd.effects.compose) and the base's own simulator.
"""

from __future__ import annotations

import numba
import numpy as np

from rigd.lti import zoh


@numba.njit(cache=True)
def _sim_cubic(Phi, Gam, C, D, K3, x0, u):
    n = u.shape[0]
    ny = C.shape[0]
    nu = u.shape[1]
    y = np.empty((n, ny))
    x = x0.copy()
    up = np.empty(nu)
    for k in range(n):
        p = C @ x
        for i in range(ny):
            y[k, i] = p[i]
        for j in range(nu):
            acc = u[k, j]
            for i in range(ny):
                acc -= K3[j, i] * p[i] * p[i] * p[i]
            up[j] = acc
        if D.shape[0] > 0:
            y[k] += D @ u[k]
        x = Phi @ x + Gam @ up
    return y


def simulate_state(A, B, C, D, x0, K3, fs: float, u: np.ndarray) -> np.ndarray:
    """Simulate x' = A x + B (u − K3 (C x)³), y = C x + D u with ZOH at fs."""
    Phi, Gam = zoh(A, B, 1.0 / fs)
    C = np.ascontiguousarray(C, dtype=float)
    D = np.ascontiguousarray(D if D is not None else np.zeros((C.shape[0], B.shape[1])), float)
    K3 = np.ascontiguousarray(np.zeros((B.shape[1], C.shape[0])) if K3 is None else K3, float)
    x0 = np.ascontiguousarray(np.zeros(A.shape[0]) if x0 is None else x0, dtype=float).ravel()
    return _sim_cubic(np.ascontiguousarray(Phi), np.ascontiguousarray(Gam), C, D, K3, x0,
                      np.ascontiguousarray(u, dtype=float))
