"""Exact output sensitivities of the general LTI model to the parameters it is linear in.

The simulated output of :class:`rigd.ident.lti.statespace.StateSpaceModel`,

    x[k+1] = A_d x[k] + B_d u_e[k],   y[k] = C x[k] + D u[k − τ] + y_off,

is linear in each of B (through B_d = Γ B, Γ the hold's discretisation of A alone), x0, C, D
and y_off; only the poles enter non-linearly. Because A is block-diagonal (real-block modal
form), the sensitivity to an entry of B or x0 of state s is a simulation of s's block alone
(one or two states), and the sensitivity to C[i, s] is state s of the model's own simulation.
:func:`output_sensitivities` returns these columns; :func:`rigd.ident.jacobian` puts them in
the fit's Jacobian beside finite differences of the poles. A forward difference of a function
linear in the parameter is the same column up to rounding, so the fit's steps are those of
the all-difference Jacobian, at a fraction of its simulations (one per pole instead of one
per parameter).
"""

from __future__ import annotations

import numpy as np

from rigd.ident import block_kernels as BK
from rigd.ident.sim_kernels import lsim_kernel
from rigd.ident.simulate import _discrete, shift_inputs


def _input_gains(A: np.ndarray, hold: str, dt: float, uu: np.ndarray):
    """(A_d, G0, G1, u_e): the discretisation of (A, I) with the model's hold, as
    :func:`rigd.ident.simulate._linear_discrete` does it; B_d = [G0 B] (ZOH) or
    [G0 B, G1 B] on u_e = [u[k], u[k+1]] (FOH; G1 None for ZOH)."""
    nx = A.shape[0]
    eye = np.eye(nx)
    blk = BK.blocks(A)
    if blk is not None:
        Ad, G, ue = BK.discrete(A, eye, dt, hold, blk[0], blk[1], uu)
    else:
        Ad, G, ue = _discrete(A, eye, dt, hold, uu)
    G = np.asarray(G, float)
    if hold == "foh":
        return np.asarray(Ad, float), G[:, :nx], G[:, nx:], ue
    return np.asarray(Ad, float), G, None, ue


def output_sensitivities(model, theta: np.ndarray, data) -> tuple[np.ndarray, np.ndarray] | None:
    """(indices, dY) with dY[:, :, k] = ∂ŷ/∂θ[indices[k]] (n, ny, k) of ``model.simulate``
    at ``theta`` on ``data``, for every parameter the output is linear in (B, C, D, x0,
    y_off; module docstring); None when the model cannot be discretised at ``theta``.

    Parameters
    ----------
    model : StateSpaceModel
    theta : ndarray
        Parameters (``model.names`` order).
    data : IdData
        Inputs ``u`` (n, nu) and the rate ``fs``, Hz.
    """
    m = model.matrices(theta)
    A, B, C, x0 = m["A"], m["B"], m["C"], m["x0"]
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        return None
    u = np.ascontiguousarray(data.u, dtype=float)
    uu = np.ascontiguousarray(shift_inputs(u, model.delays))
    Ad, G0, G1, ue = _input_gains(A, model.hold, 1.0 / float(data.fs), uu)
    if not (np.all(np.isfinite(Ad)) and np.all(np.isfinite(G0))):
        return None
    ue = np.ascontiguousarray(ue, dtype=float)
    n, nu, ny = uu.shape[0], model.nu, model.ny
    nue = ue.shape[1]
    Bd = G0 @ B if G1 is None else np.hstack([G0 @ B, G1 @ B])
    g = model.group_slices()
    c_index = {(i, s): g["c"][0] + k for k, (i, s) in enumerate(model._c_free)}
    x0_index = {s: g["x0"][0] + k for k, s in enumerate(model._x0_states)}
    idx = sorted(list(range(*g["b"])) + list(c_index.values()) + list(x0_index.values())
                 + list(range(*g["d"])) + list(range(*g["yoff"])))
    col = {p: k for k, p in enumerate(idx)}
    dY = np.zeros((n, ny, len(idx)))
    for t, s0 in model.block_states():
        b = 2 if t == "pair" else 1
        sl = slice(s0, s0 + b)
        Adb = np.ascontiguousarray(Ad[sl, sl])
        Cb = np.ascontiguousarray(C[:, sl])
        eye = np.eye(b)
        X = np.empty((n, b))    # the block's states in the model's own simulation
        lsim_kernel(Adb, np.ascontiguousarray(Bd[sl]), eye, np.ascontiguousarray(x0[sl]),
                    ue, X)
        for (i, s), p in c_index.items():
            if s0 <= s < s0 + b:
                dY[:, i, col[p]] = X[:, s - s0]
        Z = np.empty((n, b))
        for s in range(s0, s0 + b):
            for j in range(nu):        # B[s, j]: the block driven by input j along Γ e_s
                Bs = np.zeros((b, nue))
                Bs[:, j] = G0[sl, s]
                if G1 is not None:
                    Bs[:, nu + j] = G1[sl, s]
                lsim_kernel(Adb, Bs, eye, np.zeros(b), ue, Z)
                dY[:, :, col[g["b"][0] + s * nu + j]] = Z @ Cb.T
            if s in x0_index:          # x0[s]: the block's free response from e_s
                e = np.zeros(b)
                e[s - s0] = 1.0
                lsim_kernel(Adb, np.zeros((b, nue)), eye, e, ue, Z)
                dY[:, :, col[x0_index[s]]] = Z @ Cb.T
    if model.feedthrough:
        for i in range(ny):
            for j in range(nu):
                dY[:, i, col[g["d"][0] + i * nu + j]] = uu[:, j]
    if model.output_offsets:
        for i in range(ny):
            dY[:, i, col[g["yoff"][0] + i]] = 1.0
    idx = np.array(idx, int)
    return idx, dY
