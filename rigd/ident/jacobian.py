"""The Jacobian of :func:`rigd.ident.pem.fit`'s output-error residual: the structure's own
output sensitivities where it has them, forward differences elsewhere.

A structure that offers ``output_sensitivities(theta, data) -> (indices, dY)`` (the general
LTI model: :mod:`rigd.ident.lti.sensitivity`, every parameter of its simulation; that model
with input-site and additive output-site effects around it:
:meth:`rigd.effects.compose.Composed.output_sensitivities`, the base's parameters) has those
columns computed from small block simulations; one whose output offsets are added at its
end (:func:`additive_offsets`: the mechanical models, with or without state-level effects)
has theirs (ones); the other free parameters get the forward difference
``scipy.optimize.least_squares`` would take itself (``approx_derivative``, the same relative
step and bounds). Columns of parameters the output is linear in equal those differences up
to rounding; a pole's column is the exact derivative, where the difference is off by its
step.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize._numdiff import approx_derivative


def additive_offsets(structure) -> list[int]:
    """Indices of the output offsets of ``structure`` when its output is ``(…) + y_off``
    whatever the other parameters: a structure that says so (``additive_offsets``), alone or
    with effects around it (rigd.effects.compose) that act on its inputs or states only and
    leave the simulation to it (an output-site curve acts after the offset; an effect that
    simulates the states with a model of its own may not add it); else []."""
    base = structure if structure.base is None else structure.base
    effects = structure.effect_list
    if not base.additive_offsets:
        return []
    for e in effects:
        if not set(e.sites) <= {"state", "input"}:
            return []
        if e.state_simulate is not None and e.owns_state(base):
            return []
    return [int(i) for i in base.offset_index]


def linear_jacobian(structure, data, fun, free: np.ndarray, scale: np.ndarray,
                    theta_full: np.ndarray, wy: np.ndarray, skip: int, bounds,
                    diff_step: float):
    """(residual function, Jacobian function) of the scaled free parameters ``z``, or None
    when ``structure`` offers no output sensitivities.

    Parameters
    ----------
    structure, data
        As :func:`rigd.ident.pem.fit` (output error; the structure bound to ``data``).
    fun : callable
        The residual ``z -> ((y − ŷ)[skip:] · wy).ravel()`` (:func:`rigd.ident.pem.
        _residual_fn`).
    free, scale, theta_full, wy, skip
        Its free mask, parameter scales, full parameter vector, output weights (1/output
        unit) and samples left out at the start.
    bounds : (ndarray, ndarray)
        Bounds of ``z`` as given to the optimiser (its finite differences respect them).
    diff_step : float
        The optimiser's relative difference step.
    """
    # looked up on the class: a wrapper that delegates to its base (rigd.effects.compose)
    # simulates more than the base and has no such columns
    # (a composed model offers them when its effects leave the base's linearity intact:
    # rigd.effects.compose.Composed.output_sensitivities; None otherwise)
    method = type(structure).output_sensitivities
    off = additive_offsets(structure)
    if method is None and not off:
        return None

    def sens(th, d):
        out = method(structure, th, d) if method is not None else None
        if out is None and off:     # ŷ = (…) + y_off: ∂ŷ_i/∂y_off_i = 1
            dY = np.zeros((len(off), d.n, len(off)))
            dY[np.arange(len(off)), :, np.arange(len(off))] = 1.0
            out = np.asarray(off, int), dY
        return out

    free_idx = np.flatnonzero(free)
    pos = {int(p): k for k, p in enumerate(free_idx)}
    last: dict[str, np.ndarray] = {}

    def res(z):
        r = fun(z)
        last["z"], last["r"] = np.array(z, float, copy=True), r
        return r

    def r_at(z):
        if "z" in last and np.array_equal(last["z"], z):
            return last["r"]
        return res(z)

    def jac(z):
        z = np.asarray(z, float)
        r0 = r_at(z)
        th = theta_full.copy()
        th[free] = z * scale[free]
        # at a parameter set the model cannot simulate the residual is a constant penalty:
        # its differences (zeros) are the optimiser's, not the model's sensitivities
        penalty = bool(r0.size) and bool(np.all(r0 == r0[0]))
        out = None if penalty else sens(th, data)
        lin = [] if out is None else [(pos[int(p)], k) for k, p in enumerate(out[0])
                                      if int(p) in pos]
        # built as its transpose (p × m): each column a contiguous row, written once
        Jt = np.empty((z.size, r0.size))
        ny = wy.size
        done = np.zeros(z.size, bool)
        for c, k in lin:
            np.multiply(out[1][k, skip:], wy * -scale[free_idx[c]], out=Jt[c].reshape(-1, ny))
            done[c] = True
        # a sensitivity that is not finite: every column by differences (checked row by
        # row, without copying the rows)
        if not all(np.isfinite(Jt[c]).all() for c, _ in lin):
            done[:] = False
        rest = np.flatnonzero(~done)
        if rest.size:
            def sub(zr):
                zz = z.copy()
                zz[rest] = zr
                return fun(zz)

            lo, hi = (np.broadcast_to(np.asarray(b, float), z.shape)[rest] for b in bounds)
            Jt[rest] = np.atleast_2d(approx_derivative(
                sub, z[rest], method="2-point", rel_step=diff_step, f0=r0,
                bounds=(lo, hi))).reshape(r0.size, rest.size).T
        return Jt.T

    return res, jac
