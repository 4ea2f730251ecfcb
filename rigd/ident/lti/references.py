"""The black-box references as candidates of the base-model choice.

The yardstick (:mod:`rigd.ident.yardstick`) puts a plain ARX and a subspace model beside every
fit; a base model that a plain ARX beats on held-out data is a base-model choice that missed a
linear model the data support. So :func:`rigd.ident.lti.order.choose_base` lets the
references *themselves* compete: each is selected as the yardstick selects it, on the
estimation part alone (:func:`~rigd.ident.lti.arx.select_arx`: order and per-input delays by
the free-run fit on the estimation part's last third; :func:`~rigd.ident.lti.subspace.
select_subspace`: order likewise), and is carried whole into the general LTI family
(:class:`~rigd.ident.lti.statespace.StateSpaceModel`, :func:`carried_candidates`):

1. its discrete A, B, C, D go to the real-block modal basis (a similarity transform by A's
   eigenvectors: one 2×2 block per complex pair, one state per real pole), each block scaled
   so that its ``norm_rows`` entry of C is 1 (a pair: (1, 0));
2. each block's discrete pole becomes the continuous one (clipped to the family's bounds; a
   negative real pole, which no continuous pole samples to, becomes a fast real pole; a pair
   damped beyond the family's ζ bound two real poles), and its discrete B the continuous B
   that gives the block the reference's static gain with the model's hold: exactly the
   reference's input matrix for a zero-order hold;
3. the initial state and the output offsets by least squares on the estimation part, the
   rest kept (the *carried* model); and the same poles and C with B, D, x0 and offsets by
   least squares (:func:`~rigd.ident.lti.modal.gains_given_c`) — kept instead only when it
   fits the estimation part better.

So the candidate is the reference itself (to the hold and the pole bounds), never its poles
with gains fitted anew; the output-error refit in ``choose_base`` starts from it and is kept
only when it lowers the criterion on the estimation part. With a first-order hold the
input delay of the reference (nk − 1 samples behind a zero-order hold) is tried as is and one
sample longer, the better on the estimation part kept.

An ARX model's poles are those of its A polynomial (the block companion matrix of
a_1 … a_na): the states an ARX model's observer form adds for the input delays (poles at 0)
are the StateSpaceModel's per-input delays instead (its b coefficients are shifted by the
delay before the observer form is built).
"""

from __future__ import annotations

import numpy as np

from rigd.ident.lti.linear import LinearModel

#: orders tried by the references here (the yardstick's ARX orders; subspace likewise up to
#: the most states a base model gets)
ARX_ORDERS = tuple(range(1, 11)) + (15, 20, 30)
SUBSPACE_ORDERS = tuple(range(1, 11)) + (12, 16, 20, 25, 30)
#: most states of a reference carried into the base: a limit of its own (the ARX of order 20
#: on 3 outputs has 60 states; the scan's MAX_STATES is for the models it builds itself). A
#: carried reference of more than MAX_STATES states competes as it is (no output-error refit)
REF_MAX_STATES = 120


def arx_companion(a: np.ndarray) -> np.ndarray:
    """The block companion matrix of an ARX model's A polynomial, ``a`` (na, ny, ny) =
    a_1 … a_na: its na·ny eigenvalues are the model's poles."""
    na, ny = a.shape[0], a.shape[1]
    A = np.zeros((na * ny, na * ny))
    for k in range(na):
        A[k * ny:(k + 1) * ny, :ny] = -a[k]
        if k + 1 < na:
            A[k * ny:(k + 1) * ny, (k + 1) * ny:(k + 2) * ny] = np.eye(ny)
    return A


def shifted_arx(model, shift) -> LinearModel:
    """The observer form (:meth:`~rigd.ident.lti.arx.ArxModel.to_linear`) of the ARX
    ``model`` with input j's b coefficients moved ``shift[j]`` samples earlier (the delay
    left to the StateSpaceModel): na·ny states when na = nb and shift = nk − 1."""
    from dataclasses import replace

    b = np.asarray(model.b, float)
    out = np.zeros_like(b)
    for j, d in enumerate(shift):
        out[:b.shape[0] - int(d), :, j] = b[int(d):, :, j]
    used = np.flatnonzero(np.any(out != 0, axis=(1, 2)))
    out = out[:int(used[-1]) + 1 if used.size else 1]
    return replace(model, b=out).to_linear()


def reference_models(d_est) -> list[tuple[str, LinearModel, list[int]]]:
    """(name, discrete model, per-input delays behind a zero-order hold) of the ARX and
    subspace references selected on the estimation data ``d_est`` alone (module docstring);
    a reference that cannot be fitted is left out."""
    from rigd.ident.lti.arx import select_arx
    from rigd.ident.lti.subspace import select_subspace

    u, y = np.asarray(d_est.u, float), np.asarray(d_est.y, float)
    fs = float(d_est.fs)
    out = []
    try:
        sel = select_arx(u, y, ARX_ORDERS, fs=fs)
        delays = [max(int(k) - 1, 0) for k in sel.nk]
        if sel.model.na > 0:
            out.append(("arx", shifted_arx(sel.model, delays), delays))
    except (ValueError, np.linalg.LinAlgError):
        pass
    try:
        res, _ = select_subspace(u, y, SUBSPACE_ORDERS, fs=fs)
        out.append(("subspace", res.model, [0] * u.shape[1]))
    except (ValueError, np.linalg.LinAlgError):
        pass
    return out


def modal_form(ref: LinearModel, fs: float):
    """The reference's discrete model in the real-block modal basis (module docstring, 1).

    Returns (continuous poles one per block — pairs, then real poles, slowest first —,
    Z, B, C in that basis, groups) or ``None`` when A's eigenvectors do not make a usable
    basis (a defective or nearly defective A). ``groups``: (first, stop) state ranges that Z
    leaves coupled: one per block, except a pair damped beyond the family's ζ bound
    (:data:`~rigd.ident.lti.statespace.ZETA_MAX`), which becomes two real poles σ ± ω_d in
    one group of two states (the basis (1, 1), (1, −1) of the pair's plane)."""
    from rigd.ident.lti.modal import poles_from_discrete
    from rigd.ident.lti.statespace import ZETA_MAX

    A = np.asarray(ref.A, float)
    w, V = np.linalg.eig(A)
    tiny = [1e-12 * max(abs(v), 1e-300) for v in w]
    pairs = [k for k in range(len(w)) if w[k].imag > tiny[k]]
    reals = [k for k in range(len(w)) if abs(w[k].imag) <= tiny[k]]
    if 2 * len(pairs) + len(reals) != len(w):
        return None

    # each eigenvalue's continuous pole, once
    cont = {k: poles_from_discrete(np.array([[w[k].real, w[k].imag], [-w[k].imag, w[k].real]]),
                                   fs)[0] for k in pairs}
    cont.update({k: poles_from_discrete(np.array([[w[k].real]]), fs)[0] for k in reals})
    split = [k for k in pairs if -cont[k].real > ZETA_MAX * abs(cont[k])]
    pairs = sorted((k for k in pairs if k not in split), key=lambda k: abs(cont[k]))
    lam, cols, groups = [], [], []
    for k in pairs:
        cols += [V[:, k].real, V[:, k].imag]
        lam.append(cont[k])
        groups.append((2 * len(groups), 2 * len(groups) + 2))
    s = len(cols)
    for k in sorted(reals + split, key=lambda k: abs(cont[k])):
        lm = cont[k]
        if k in split:
            cols += [V[:, k].real + V[:, k].imag, V[:, k].real - V[:, k].imag]
            lam += [complex(lm.real + lm.imag, 0.0), complex(lm.real - lm.imag, 0.0)]
            groups.append((s, s + 2))
            s += 2
        else:
            cols.append(V[:, k].real)
            lam.append(lm)
            groups.append((s, s + 1))
            s += 1
    T = np.column_stack(cols)
    if np.linalg.cond(T) > 1e10:
        return None
    Ti = np.linalg.inv(T)
    return lam, Ti @ A @ T, Ti @ np.asarray(ref.B, float), np.asarray(ref.C, float) @ T, groups


def _normalised(model_blocks, Z, B, C, w_out):
    """Each block scaled (a pair: rotated and scaled) so that C is 1 (a pair: (1, 0)) at the
    output row where the block's column of C is largest relative to that output's spread;
    returns (Z, B, C, norm_rows)."""
    S = np.eye(Z.shape[0])
    rows = []
    for t, s in model_blocks:
        k = slice(s, s + (2 if t == "pair" else 1))
        r = int(np.argmax(np.linalg.norm(C[:, k], axis=1) * w_out))
        rows.append(r)
        if t == "pair":
            p, q = C[r, s], C[r, s + 1]
            blk = np.array([[p, q], [-q, p]])
        else:
            blk = np.array([[C[r, s]]])
        if np.linalg.norm(blk) > 0:
            S[k, k] = blk
    Si = np.linalg.inv(S)
    return S @ Z @ Si, S @ B, C @ Si, rows


def _continuous_b(model, lam, Z, Bd, groups) -> np.ndarray:
    """Per group of states the continuous B giving it the reference's static gain with the
    model's hold, (I − Φ)⁻¹ Γ B = (I − Z)⁻¹ Bd (Φ, Γ: the model's discrete blocks, Γ = Γ0 +
    Γ1 with a first-order hold): for an unclipped pole under a zero-order hold, Γ B = Bd."""
    from scipy.linalg import block_diag

    from rigd.lti import foh, zoh

    dt = 1.0 / model.fs
    Ac = block_diag(*[np.array([[v.real, v.imag], [-v.imag, v.real]]) if t == "pair"
                      else np.array([[v.real]])
                      for (t, _), v in zip(model.block_states(), lam)])
    Bc = np.zeros_like(Bd)
    for a, b in groups:
        k = slice(a, b)
        eye = np.eye(b - a)
        if model.hold == "foh":
            Phi, G0, G1 = foh(Ac[k, k], eye, dt)
            G = G0 + G1
        else:
            Phi, G = zoh(Ac[k, k], eye, dt)
        dc = np.linalg.lstsq(eye - Z[k, k], Bd[k], rcond=1e-12)[0]
        Bc[k] = np.linalg.lstsq(G, (eye - Phi) @ dc, rcond=1e-12)[0]
    return Bc


def carried_candidates(data, d_est, est: slice, val: slice, refs, hold: str, skip: int,
                       limit: int) -> list:
    """General LTI candidates carrying each reference of ``refs`` (:func:`reference_models`)
    of at most ``limit`` states whole (module docstring): per reference the better on the
    estimation part of the carried model and its gains by least squares; ``skip``: samples
    left out of every criterion (the same for all candidates)."""
    from rigd.ident.lti.candidates import Candidate, score
    from rigd.ident.lti.modal import gains_given_c
    from rigd.ident.lti.statespace import StateSpaceModel

    y = np.asarray(d_est.y, float)
    w_out = 1.0 / np.maximum(y.std(axis=0), 1e-300)
    out = []
    for _name, ref, delays in refs:
        if not 1 <= ref.order <= limit:
            continue
        try:
            form = modal_form(ref, float(data.fs))
        except np.linalg.LinAlgError:
            form = None
        if form is None:
            continue
        lam, Z, Bd, Cd, groups = form
        npair = sum(1 for v in lam if v.imag > 0)
        feed = bool(np.any(np.asarray(ref.D) != 0))
        tries = [list(delays)] + ([[d + 1 for d in delays]] if hold == "foh" else [])
        best = None
        for dl in tries:
            m = StateSpaceModel(d_est.input_names, d_est.output_names, data.fs, npair,
                                len(lam) - npair, 0, dl, hold, feed)
            Zn, Bn, Cn, rows = _normalised(m.block_states(), Z, Bd, Cd, w_out)
            m = StateSpaceModel(d_est.input_names, d_est.output_names, data.fs, npair,
                                len(lam) - npair, 0, dl, hold, feed, norm_rows=rows)
            m.set_record(d_est.n)
            lo, hi = m.bounds()
            npole = 2 * m.nc + m.nr
            th = np.clip(m.pole_params(lam), lo[:npole] + 1e-9, hi[:npole] - 1e-9)
            lam_m = m.poles_c(np.concatenate([th, np.zeros(len(m.names) - npole)]))
            try:
                Bc = _continuous_b(m, lam_m, Zn, Bn, groups)
                thetas = [gains_given_c(m, lam_m, Cn, d_est, skip, fixed=(Bc, ref.D)),
                          gains_given_c(m, lam_m, Cn, d_est, skip)]
            except (np.linalg.LinAlgError, ValueError):
                continue
            for theta in thetas:
                b, fe, fv = score(m, theta, data, est, val, skip)
                if np.isfinite(b) and (best is None or b < best.bic):
                    best = Candidate("lti", m.nx, m, theta, b, fe, fv, len(m.names), skip)
        if best is not None:
            out.append(best)
    return out
