"""Output sensitivities of the general LTI model to all of its simulation's parameters.

The simulated output of :class:`rigd.ident.lti.statespace.StateSpaceModel`,

    x[k+1] = A_d x[k] + B_d u_e[k],   y[k] = C x[k] + D u[k − τ] + y_off,

is linear in each of B (through B_d = Γ B, Γ the hold's discretisation of A alone), x0, C, D
and y_off; only the poles enter non-linearly. Because A is block-diagonal (real-block modal
form), every column is a simulation of one block (one or two states):

* B or x0 of state s: the block driven by Γ e_s, or its free response from e_s;
* C[i, s]: state s of the model's own simulation; D and y_off: the input, ones;
* a pole's parameter θ (log-frequency, damping ratio): the sensitivity equation
  z[k+1] = A_d z[k] + (∂A_d/∂θ) x[k] + (∂B_d/∂θ) u_e[k], ∂y/∂θ = C z, driven by the block's
  own states x; ∂A_d and ∂B_d are a central difference of the block's exact (ZOH/FOH)
  discretisation, a 2 × 2 matrix function, so the column is exact to about 1e-9.

:func:`output_sensitivities` returns these columns; :func:`rigd.ident.jacobian` puts them in
the fit's Jacobian in place of forward differences of the whole simulation (one small
block simulation per parameter instead of one simulation of the model).
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


def _pole_parameters(model) -> dict[int, list[int]]:
    """first state of a block -> indices of the parameters of its pole(s) in theta."""
    out, kc, kr = {}, 0, 0
    for t, s0 in model.block_states():
        if t == "pair":
            out[s0] = [2 * kc, 2 * kc + 1]
            kc += 1
        elif t == "real":
            out[s0] = [2 * model.nc + kr]
            kr += 1
    return out


#: step of the central difference of a block's discretisation in its pole parameters (a
#: log-frequency and a damping ratio): the truncation error ~ STEP² and the rounding error
#: ~ 1e-16 / STEP are both below 1e-9 of the derivative
STEP = 1e-5


def _block_derivative(model, theta, p, sl, Bb, dt, uu):
    """(∂A_d, ∂B_d) of one block's discretisation (the model's hold) in parameter ``p``
    (a pole's), by a central difference of the 1×1 or 2×2 block's exact discretisation."""
    out = []
    for sgn in (1.0, -1.0):
        th = np.array(theta, float, copy=True)
        th[p] += sgn * STEP
        Ab = model.matrices(th)["A"][sl, sl]
        Adb, G0, G1, _ = _input_gains(Ab, model.hold, dt, uu)
        out.append((Adb, G0 @ Bb if G1 is None else np.hstack([G0 @ Bb, G1 @ Bb])))
    (a1, b1), (a2, b2) = out
    return (a1 - a2) / (2 * STEP), (b1 - b2) / (2 * STEP)


def output_sensitivities(model, theta: np.ndarray, data) -> tuple[np.ndarray, np.ndarray] | None:
    """(indices, dY) with dY[k] = ∂ŷ/∂θ[indices[k]] (k, n, ny) of ``model.simulate``
    at ``theta`` on ``data``, for every parameter of the simulation (the poles, B, C, D, x0,
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
    pole_of = _pole_parameters(model)
    idx = sorted(list(range(*g["b"])) + list(c_index.values()) + list(x0_index.values())
                 + list(range(*g["d"])) + list(range(*g["yoff"]))
                 + [p for ps in pole_of.values() for p in ps])
    col = {p: k for k, p in enumerate(idx)}
    dY = np.zeros((len(idx), n, ny))
    dt = 1.0 / float(data.fs)
    for t, s0 in model.block_states():
        b = 2 if t == "pair" else 1
        sl = slice(s0, s0 + b)
        Adb = np.ascontiguousarray(Ad[sl, sl])
        Cb = np.ascontiguousarray(C[:, sl])
        eye = np.eye(b)
        X = np.empty((n, b))    # the block's states in the model's own simulation
        lsim_kernel(Adb, np.ascontiguousarray(Bd[sl]), eye, np.ascontiguousarray(x0[sl]),
                    ue, X)
        if pole_of.get(s0):
            W = np.ascontiguousarray(np.hstack([X, ue]))
            Yp = np.empty((n, ny))
            for p in pole_of[s0]:
                dAd, dBd = _block_derivative(model, theta, p, sl, B[sl], dt, uu[:2])
                if not (np.all(np.isfinite(dAd)) and np.all(np.isfinite(dBd))):
                    return None
                # the sensitivity equation: z[k+1] = A_d z[k] + ∂A_d x[k] + ∂B_d u_e[k]
                lsim_kernel(Adb, np.ascontiguousarray(np.hstack([dAd, dBd])), Cb,
                            np.zeros(b), W, Yp)
                dY[col[p]] = Yp
        for (i, s), p in c_index.items():
            if s0 <= s < s0 + b:
                dY[col[p], :, i] = X[:, s - s0]
        Z = np.empty((n, b))
        for s in range(s0, s0 + b):
            for j in range(nu):        # B[s, j]: the block driven by input j along Γ e_s
                Bs = np.zeros((b, nue))
                Bs[:, j] = G0[sl, s]
                if G1 is not None:
                    Bs[:, nu + j] = G1[sl, s]
                lsim_kernel(Adb, Bs, eye, np.zeros(b), ue, Z)
                dY[col[g["b"][0] + s * nu + j]] = Z @ Cb.T
            if s in x0_index:          # x0[s]: the block's free response from e_s
                e = np.zeros(b)
                e[s - s0] = 1.0
                lsim_kernel(Adb, np.zeros((b, nue)), eye, e, ue, Z)
                dY[col[x0_index[s]]] = Z @ Cb.T
    if model.feedthrough:
        for i in range(ny):
            for j in range(nu):
                dY[col[g["d"][0] + i * nu + j], :, i] = uu[:, j]
    if model.output_offsets:
        for i in range(ny):
            dY[col[g["yoff"][0] + i], :, i] = 1.0
    idx = np.array(idx, int)
    return idx, dY
