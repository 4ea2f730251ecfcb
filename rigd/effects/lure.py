"""A Lur'e block on the general LTI base: static curves of the signals fed back into its states.

The state site of ``static_nonlinearity`` (rigd.effects.static_nonlinearity). A process whose
rates depend nonlinearly on its own levels (a reaction rate rising exponentially with the
temperature, an outflow rising with the square root of a level) is not a linear model with a
curve before or after it: the curve acts *inside* the dynamics. With the base in real-block
modal form (rigd.ident.lti.statespace, x the modal states, ŷ = C x + D u + y_off its output)
the block is

    ẋ = A x + B u + F φ(u, ŷ),    φ = [(v − c_v)^k  for v in (u_1 … u_nu, ŷ_1 … ŷ_ny),
                                        k = 2 … degree],

each signal's powers about a fixed centre c_v (the estimation part's mean, in the signal's
unit), F (states × terms) free, in state units per second per unit of the term. It is a
Lur'e (feedback) form whose static part is separable — one curve per signal, no products of
two signals — so its size grows with states × signals, not with the number of monomials of a
full polynomial state-space model. F = 0 is the base exactly.

Simulation: the base's exact discretisation (ZOH/FOH, per-input delays,
rigd.ident.simulate) with φ held over each sample (ZOH of (A, F)), one compiled
sample-by-sample kernel (:func:`simulate_lure`).
"""

from __future__ import annotations

import numba
import numpy as np

from rigd.ident.simulate import _discrete, shift_inputs
from rigd.lti import zoh

__all__ = ["simulate_lure", "terms", "state_responses"]


@numba.njit(cache=True, inline="always")
def _powers(phi, t, d, m):  # pragma: no cover - compiled
    """d², d³, … d^(m+1) into phi[t:t+m]; the next free index."""
    p = d
    for _ in range(m):
        p = p * d
        phi[t] = p
        t += 1
    return t


@numba.njit(cache=True)
def _lure_kernel(Ad, Bd, Gf, C, D, yoff, x0, ue, us, cu, cy, degree, y):  # pragma: no cover
    n, nx = ue.shape[0], Ad.shape[0]
    ny, nu = C.shape[0], us.shape[1]
    m = degree - 1
    x = x0.copy()
    xn = np.empty(nx)
    phi = np.empty((nu + ny) * m)
    for k in range(n):
        for i in range(ny):
            acc = yoff[i]
            for s in range(nx):
                acc += C[i, s] * x[s]
            for j in range(nu):
                acc += D[i, j] * us[k, j]
            y[k, i] = acc
        t = 0
        for j in range(nu):
            t = _powers(phi, t, us[k, j] - cu[j], m)
        for i in range(ny):
            t = _powers(phi, t, y[k, i] - cy[i], m)
        ok = True
        for s in range(nx):
            acc = 0.0
            for q in range(nx):
                acc += Ad[s, q] * x[q]
            for q in range(ue.shape[1]):
                acc += Bd[s, q] * ue[k, q]
            for q in range(phi.shape[0]):
                acc += Gf[s, q] * phi[q]
            xn[s] = acc
            if not np.isfinite(acc) or abs(acc) > 1e150:
                ok = False
        if not ok:  # the loop ran away: no output from here on
            for kk in range(k + 1, n):
                for i in range(ny):
                    y[kk, i] = np.nan
            return
        for s in range(nx):
            x[s] = xn[s]


def terms(nu: int, ny: int, degree: int) -> list[tuple[str, int, int]]:
    """The terms of φ in order: (``"u"`` or ``"y"``, channel, power)."""
    return ([("u", j, k) for j in range(nu) for k in range(2, degree + 1)]
            + [("y", i, k) for i in range(ny) for k in range(2, degree + 1)])


def simulate_lure(lp, x0, yoff, F, cu, cy, degree: int, u, fs: float) -> np.ndarray:
    """Output (n, ny) of the base's linear part ``lp`` (rigd.ident.model.LinearPart) from
    state ``x0`` with offsets ``yoff`` and the feedback block ``F`` (nx × (nu+ny)·(degree−1),
    continuous) about the centres ``cu`` (nu,) and ``cy`` (ny,); NaN from the sample on
    which the loop runs away."""
    us = np.ascontiguousarray(shift_inputs(np.ascontiguousarray(u, dtype=float), lp.delays))
    A = np.asarray(lp.A, float)
    Ad, Bd, ue = _discrete(A, np.asarray(lp.B, float), 1.0 / fs, lp.hold, us)
    Gf = zoh(A, np.asarray(F, float), 1.0 / fs)[1]
    y = np.empty((us.shape[0], lp.ny))
    _lure_kernel(np.ascontiguousarray(Ad), np.ascontiguousarray(Bd), np.ascontiguousarray(Gf),
                 np.ascontiguousarray(lp.C, dtype=float),
                 np.ascontiguousarray(lp.D, dtype=float), np.asarray(yoff, float),
                 np.ascontiguousarray(x0, dtype=float), np.ascontiguousarray(ue), us,
                 np.asarray(cu, float), np.asarray(cy, float), int(degree), y)
    return y


def state_responses(lp, signals: np.ndarray, fs: float) -> np.ndarray:
    """Responses (n, ny, nx·k) of the linear part ``lp`` to each column of ``signals``
    (n, k) fed into each state in turn (ZOH, no delay): the first-order regressors of F,
    ordered state-major (column s·k + t = state s, signal t)."""
    from rigd.ident.model import LinearPart
    from rigd.ident.simulate import simulate_linear

    n, k = signals.shape
    nx, ny = lp.nx, lp.ny
    out = np.empty((n, ny, nx * k))
    for s in range(nx):
        Bs = np.zeros((nx, 1))
        Bs[s, 0] = 1.0
        part = LinearPart(np.asarray(lp.A, float), Bs, np.asarray(lp.C, float),
                          np.zeros((ny, 1)), None, (0,), "zoh")
        for t in range(k):
            out[:, :, s * k + t] = simulate_linear(part, np.zeros(nx), signals[:, t:t + 1], fs)
    return out
