"""Start values of the general LTI family (:mod:`rigd.ident.lti.statespace`) from poles.

Given one continuous pole per block (from a subspace model's A, :func:`poles_from_discrete`),
the gains follow by linear least squares, exactly for the sampled model the simulator runs
(same ZOH/FOH discretisation, same delays):

1. per output, the response of every block to every input enters linearly with a complex
   (pair) or real (real pole, integrator) coefficient g (a transfer-function numerator per
   block, input and output), together with the blocks' free responses, D and the offsets;
2. per block, the best rank-one g ≈ c bᵀ (SVD) gives that block's column of C and row of B
   (a shared state set: rank one is what one state block can realise), normalised so that
   the block's ``norm_row`` entry of C is 1;
3. with A and C fixed the output is linear in B, x0, D and the offsets: one least-squares
   solve over all outputs (each weighted by 1/std) gives them.

Every block response is a scalar (complex for a pair) first-order recursion run by
``scipy.signal.lfilter``: ξ[k+1] = μ ξ[k] + γ0 u[k] + γ1 u[k+1].
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from rigd.ident.simulate import shift_inputs
from rigd.lti import foh, zoh


def poles_from_discrete(Ad: np.ndarray, fs: float) -> list[complex]:
    """Continuous poles (rad/s) of a discrete A: one per real eigenvalue, the upper one of each
    complex pair; a negative real eigenvalue becomes a fast real pole, |z| ≥ 1 a slow one."""
    out = []
    floor = 1e-9 * fs
    for z in np.linalg.eigvals(np.asarray(Ad, float)):
        if z.imag < -1e-12 * max(abs(z), 1e-300):
            continue
        if abs(z.imag) <= 1e-12 * max(abs(z), 1e-300):
            r = abs(z.real)
            s = np.log(r) * fs if r > 0 else -np.pi * fs
            out.append(complex(min(s, -floor), 0.0))
        else:
            s = np.log(z) * fs
            out.append(complex(min(s.real, -floor * abs(s)), s.imag))
    return sorted(out, key=abs)


def _scalar_block(lam: complex, dt: float, hold: str):
    """(μ, γ0, γ1) of the complex (pair) or real recursion of one block."""
    if lam.imag > 0:
        A = np.array([[lam.real, lam.imag], [-lam.imag, lam.real]])
        e1 = np.array([[1.0], [0.0]])
        if hold == "foh":
            Ad, B0, B1 = foh(A, e1, dt)
            return complex(Ad[0, 0], Ad[1, 0]), complex(B0[0, 0], B0[1, 0]), complex(
                B1[0, 0], B1[1, 0])
        Ad, Bd = zoh(A, e1, dt)
        return complex(Ad[0, 0], Ad[1, 0]), complex(Bd[0, 0], Bd[1, 0]), 0j
    A = np.array([[lam.real]])
    one = np.array([[1.0]])
    if hold == "foh":
        Ad, B0, B1 = foh(A, one, dt)
        return complex(Ad[0, 0]), complex(B0[0, 0]), complex(B1[0, 0])
    Ad, Bd = zoh(A, one, dt)
    return complex(Ad[0, 0]), complex(Bd[0, 0]), 0j


def block_responses(lam, u: np.ndarray, fs: float, hold: str):
    """(R, F): R[b] (n, nu) complex response of block b from zero state to each input alone
    (unit gain into its first state), F[b] (n,) its free response μ^k from a unit state."""
    n = u.shape[0]
    un = np.empty_like(u)
    un[:-1], un[-1] = u[1:], u[-1]
    R, F = [], []
    k = np.arange(n)
    for lm in lam:
        mu, g0, g1 = _scalar_block(complex(lm), 1.0 / fs, hold)
        v = g0 * u + g1 * un
        R.append(lfilter([0.0, 1.0], [1.0, -mu], v, axis=0))
        F.append(mu ** k)
    return R, F


def _lstsq(M: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares with columns normalised (regressors of very different sizes)."""
    nrm = np.linalg.norm(M, axis=0)
    nrm[nrm == 0] = 1.0
    return np.linalg.lstsq(M / nrm, y, rcond=1e-12)[0] / (nrm if y.ndim == 1 else nrm[:, None])


def gains_by_least_squares(model, lam, data, skip: int = 0) -> np.ndarray:
    """theta of ``model`` (a :class:`~rigd.ident.lti.statespace.StateSpaceModel`) with the
    poles ``lam`` (one per block) and every gain, x0 and offset by least squares (module
    docstring); the first ``skip`` samples are left out of the least squares."""
    u = shift_inputs(np.ascontiguousarray(data.u, float), model.delays)
    y = np.asarray(data.y, float)
    n, nu, ny = u.shape[0], model.nu, model.ny
    blocks = model.block_states()
    R, F = block_responses(lam, u, float(data.fs), model.hold)
    # 1. per output: a complex / real coefficient per (block, input)
    cols = []
    for (t, _), r, f in zip(blocks, R, F):
        for j in range(nu):
            cols += [r[:, j].real, -r[:, j].imag] if t == "pair" else [r[:, j].real]
        if t == "pair":
            cols += [f.real, -f.imag]
        elif t == "real" or not model.output_offsets:
            cols.append(f.real)
    if model.feedthrough:
        cols += [u[:, j] for j in range(nu)]
    cols.append(np.ones(n))
    G = np.column_stack(cols)
    coef = _lstsq(G[skip:], y[skip:])                       # (ncols, ny)
    Bm = np.zeros((model.nx, nu))
    Cm = np.zeros((ny, model.nx))
    pos = 0
    for (t, s), row in zip(blocks, model.norm_rows):
        if t == "pair":
            g = (coef[pos:pos + 2 * nu:2] + 1j * coef[pos + 1:pos + 2 * nu:2]).T   # (ny, nu)
            pos += 2 * nu + 2
        else:
            g = coef[pos:pos + nu].T.astype(complex)
            pos += nu + (1 if t == "real" or not model.output_offsets else 0)
        U, S, Vh = np.linalg.svd(g)
        c, b = U[:, 0] * S[0], Vh[0]
        if abs(c[row]) < 1e-12 * max(np.max(np.abs(c)), 1e-300):
            c = np.zeros(ny, complex)
            c[row], b = 1.0, np.zeros(nu, complex)
        b, c = b * c[row], c / c[row]
        if t == "pair":
            Bm[s], Bm[s + 1] = b.real, b.imag
            Cm[:, s], Cm[:, s + 1] = c.real, -c.imag
        else:
            Bm[s], Cm[:, s] = b.real, c.real
    # 3. A and C fixed: B, x0, D, offsets jointly
    return gains_given_c(model, lam, Cm, data, skip, R=R, F=F, u=u)


def gains_given_c(model, lam, Cm: np.ndarray, data, skip: int = 0, fixed=None, R=None, F=None,
                  u=None) -> np.ndarray:
    """theta of ``model`` with the poles ``lam`` and C = ``Cm`` (normalised form) fixed: B,
    x0, D and the offsets by one linear least-squares solve over all outputs, each weighted
    by 1/std (the output is linear in them once A and C are fixed); the first ``skip``
    samples left out. ``fixed`` = (B, D): those kept too, only x0 and the offsets solved.
    ``R``, ``F``, ``u``: the block responses and shifted inputs when already computed."""
    if u is None:
        u = shift_inputs(np.ascontiguousarray(data.u, float), model.delays)
    if R is None or F is None:
        R, F = block_responses(lam, u, float(data.fs), model.hold)
    y = np.asarray(data.y, float)
    n, nu, ny = u.shape[0], model.nu, model.ny
    w = 1.0 / np.maximum(y.std(axis=0), 1e-300)
    cols, what = [], []
    for (t, s), r, f in zip(model.block_states(), R, F):
        c = Cm[:, s] - 1j * Cm[:, s + 1] if t == "pair" else Cm[:, s].astype(complex)
        units = (1.0, 1j) if t == "pair" else (1.0,)
        for q, unit in enumerate(units):
            for j in range(nu):
                cols.append(((unit * r[:, j])[:, None] * c[None, :]).real * w)
                what.append(("b", s + q, j))
            if t != "int" or not model.output_offsets:
                cols.append(((unit * f)[:, None] * c[None, :]).real * w)
                what.append(("x0", s + q, 0))
    for i in range(ny):
        if model.feedthrough:
            for j in range(nu):
                z = np.zeros((n, ny))
                z[:, i] = u[:, j] * w[i]
                cols.append(z)
                what.append(("d", i, j))
        z = np.zeros((n, ny))
        z[:, i] = w[i]
        cols.append(z)
        what.append(("yoff", i, 0))
    Bm, D = np.zeros((model.nx, nu)), np.zeros((ny, nu))
    target = (y * w)[skip:].ravel()
    if fixed is not None:
        Bm, D = np.array(fixed[0], float), np.array(fixed[1], float)
        keep = []
        for col, (kind, a, b) in zip(cols, what):
            if kind in ("b", "d"):
                target = target - col[skip:].ravel() * (Bm[a, b] if kind == "b" else D[a, b])
            else:
                keep.append((col, (kind, a, b)))
        cols, what = [k[0] for k in keep], [k[1] for k in keep]
    M = np.column_stack([c[skip:].ravel() for c in cols])
    sol = _lstsq(M, target)
    x0 = np.zeros(model.nx)
    yoff = np.zeros(ny)
    for (kind, a, b), v in zip(what, sol):
        if kind == "b":
            Bm[a, b] = v
        elif kind == "x0":
            x0[a] = v
        elif kind == "d":
            D[a, b] = v
        else:
            yoff[a] = v
    return model.pack(lam, Bm, Cm, D, None, x0, yoff if model.output_offsets else None)


def match_poles(model, candidates) -> list[complex]:
    """One pole per block of ``model`` from ``candidates`` (continuous, rad/s): the slowest
    pairs and real poles first; missing ones spread over the band."""
    fs = model.fs
    pairs = [c for c in candidates if c.imag > 0]
    reals = [c for c in candidates if c.imag == 0 and abs(c) > 1e-9 * fs]
    lo, hi = model.bounds()
    out = []
    for k in range(model.nc):
        out.append(pairs[k] if k < len(pairs) else
                   complex(-0.3 * 2 * np.pi * fs * 0.05 * (k + 1),
                           0.95 * 2 * np.pi * fs * 0.05 * (k + 1)))
    for k in range(model.nr):
        out.append(reals[k] if k < len(reals) else complex(-2 * np.pi * fs * 0.01 * (k + 1), 0))
    out += [0j] * model.ni
    th = np.clip(model.pole_params(out), lo[:2 * model.nc + model.nr] + 1e-9,
                 hi[:2 * model.nc + model.nr] - 1e-9)
    return model.poles_c(np.concatenate([th, np.zeros(len(model.names) - len(th))]))


def subspace_poles_by_order(data, orders, delays=None) -> dict[int, list[complex]]:
    """Continuous poles (rad/s) of the subspace models of every order in ``orders`` from ONE
    decomposition of ``data`` (inputs shifted by ``delays``).

    The LQ decomposition and the SVD of L₃₂ of :func:`rigd.ident.lti.subspace.n4sid` do not
    depend on the order: each order's A follows from the first ``order`` columns of the
    extended observability matrix by shift invariance. Only A is needed here (the gains are
    fitted by :func:`gains_by_least_squares`), so n4sid's B/D/K/x0 steps are skipped. An order
    the record or horizon cannot support is left out.
    """
    from rigd.ident.lti.lsq import stacked_r
    from rigd.ident.lti.subspace import _hankel_rows, default_horizon

    u = np.asarray(data.u, float)
    if delays is not None:
        u = shift_inputs(u, delays)
    y = np.asarray(data.y, float)
    n, nu = u.shape
    ny = y.shape[1]
    orders = [int(o) for o in orders if int(o) >= 1]
    if not orders:
        return {}
    i = default_horizon(n, nu, ny, max(orders))
    du = (u - u.mean(0)) / np.maximum(u.std(0), 1e-300)
    dy = (y - y.mean(0)) / np.maximum(y.std(0), 1e-300)
    j = n - 2 * i + 1
    r1, r2, r3 = i * nu, i * (nu + ny), i * ny
    if j < 2 * (r1 + r2 + r3):
        return {}
    try:
        L = stacked_r(_hankel_rows([(du, i), (du, 0), (dy, 0), (dy, i)], i), j,
                      r1 + r2 + r3).T
        U1, sv, _ = np.linalg.svd(L[r1 + r2:, r1:r1 + r2], full_matrices=False)
    except (np.linalg.LinAlgError, ValueError):
        return {}
    out = {}
    for nx in orders:
        if nx >= r3 or nx > len(sv):
            continue
        Gam = U1[:, :nx] * np.sqrt(sv[:nx])
        A = np.linalg.lstsq(Gam[:-ny], Gam[ny:], rcond=None)[0]
        out[nx] = poles_from_discrete(A, float(data.fs))
    return out


def subspace_poles(data, order: int, delays=None) -> list[complex]:
    """Continuous poles (rad/s) of an ``order``-state subspace model of ``data``
    (:func:`subspace_poles_by_order`); [] when the record is too short for that order."""
    return subspace_poles_by_order(data, [order], delays).get(int(order), [])


def initial_theta(model, data) -> np.ndarray:
    """Start values: poles of a subspace model of the model's order, matched to its blocks
    (:func:`match_poles`), gains by :func:`gains_by_least_squares`."""
    order = model.nx - model.ni
    cands = subspace_poles(data, order, model.delays) if order > 0 else []
    return gains_by_least_squares(model, match_poles(model, cands), data)
