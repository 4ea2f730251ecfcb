"""The linearised refit: an effect's signature beyond what the base model's own parameters
absorb.

A linear fit absorbs a strong nonlinearity into distorted linear parameters (a friction into
a spring and too much damping, a saturating valve into a wrong gain and time constants);
after that, the residual alone barely correlates with the effect's first-order response while
a joint step of the effect *and* the base parameters explains most of it. So the residual is
regressed on the effect's regressors together with the base model's sensitivities ∂ŷ/∂θ
(:func:`rigd.effects.detectability.parameter_responses`, one simulation per parameter, cached
on the context) and a constant per output, on the estimation part; the share is what the
effect's regressors add to the sensitivities alone, with an F test on an
autocorrelation-corrected sample size. The share is in-sample (a strong effect moves the
linear parameters further than a first-order step extrapolates); the refit then decides out
of sample. Used by ``friction`` (promoted from the dry-friction probe),
``static_nonlinearity`` and the delay scan.

The sensitivities are the same for every regressor tried on one context, so their column
space is factored once (:class:`_Basis`, an SVD truncated as ``numpy.linalg.lstsq`` truncates)
and each regressor is fitted to what that space leaves (Frisch–Waugh–Lovell: the regressors'
coefficients and the residual of the joint least-squares fit are those of the projected
regressors on the projected residual).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from rigd.effects.context import Context
from rigd.effects.detectability import parameter_responses
from rigd.effects.signature import SignatureFit, effective_n


def joint_signature(ctx: Context, regs: list[np.ndarray]) -> SignatureFit:
    """The linearised refit of the regressors ``regs`` (each (n, ny)) on ``ctx``: share and
    F test beyond the base model's sensitivities, ``beta`` the regressors' coefficients
    (score = score_est = the in-sample share)."""
    basis = _basis(ctx)
    if basis is None or not regs:
        return SignatureFit(0.0, np.zeros(len(regs)), 1.0, len(regs))
    share, p, beta = joint_share(basis, np.stack(regs, axis=-1)[ctx.est])
    return SignatureFit(share, beta, p, len(regs), share)


def sensitivities(ctx: Context) -> np.ndarray | None:
    """∂ŷ/∂θ of the base model over the whole record, (n, ny, q), from the stepped
    simulations of :func:`rigd.effects.detectability.parameter_responses` (the parameters
    that move the output) and one constant column per output; None if one failed."""
    y0 = np.asarray(ctx.yhat, float)
    cols = []
    for _, h, yi in parameter_responses(ctx):
        if yi is None:
            return None
        d = (yi - y0) / h
        if np.all(np.isfinite(d)) and np.any(d):
            cols.append(d)
    for i in range(ctx.ny):
        c = np.zeros_like(y0)
        c[:, i] = 1.0
        cols.append(c)
    return np.stack(cols, axis=-1)


@dataclass(frozen=True)
class _Basis:
    """The base's sensitivities on the estimation part of one context, factored once.

    Attributes
    ----------
    w : ndarray (ny,)
        Output weights, 1/std of the measured output (as the fit weights them).
    Q : ndarray (m, r)
        Orthonormal basis of the weighted sensitivities' column space (m = n_est·ny).
    r0 : ndarray (m,)
        The weighted residual less its projection on that space.
    sse0, ree : float
        ``r0 · r0`` (the sensitivities' fit) and the weighted residual's energy.
    q : int
        Columns of the sensitivities (the F test's degrees of freedom count them).
    tol : float
        Singular values below this are dropped (numpy.linalg.lstsq's default cut-off).
    neff : float
        Effective sample size of the residual (autocorrelation-corrected, all outputs).
    """

    w: np.ndarray
    Q: np.ndarray
    r0: np.ndarray
    sse0: float
    ree: float
    q: int
    tol: float
    neff: float


def _basis(ctx: Context) -> _Basis | None:
    """The factored sensitivities of ``ctx`` (cached on it); None without them."""
    if "linearised_basis" not in ctx.cache:
        J = sensitivities(ctx)
        ctx.cache["linearised_basis"] = None if J is None else factor(
            J[ctx.est], ctx.residual[ctx.est], ctx.y[ctx.est])
    return ctx.cache["linearised_basis"]


def factor(J: np.ndarray, residual: np.ndarray, y: np.ndarray) -> _Basis | None:
    """:class:`_Basis` of the sensitivities ``J`` (n, ny, q) for the base residual
    (n, ny) of the measured output ``y`` (n, ny), all on the estimation part; None when a
    sensitivity is not finite."""
    w = 1.0 / np.maximum(np.std(y, axis=0), 1e-300)
    re = (residual * w).reshape(-1)
    Xe = (J * w[None, :, None]).reshape(re.size, -1)
    if not np.all(np.isfinite(Xe)):
        return None
    nrm = np.linalg.norm(Xe, axis=0)
    nrm[nrm == 0] = 1.0
    U, s, _ = np.linalg.svd(Xe / nrm, full_matrices=False)
    tol = np.finfo(float).eps * max(Xe.shape) * (s[0] if s.size else 0.0)
    Q = U[:, s > tol]
    r0 = re - Q @ (Q.T @ re)
    neff = min(effective_n(residual[:, i]) for i in range(residual.shape[1]))
    return _Basis(w, Q, r0, float(r0 @ r0), float(re @ re), Xe.shape[1], tol,
                  neff * residual.shape[1])


def joint_share(basis: _Basis, G: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(share, F-test p, coefficients): the share of the base residual's energy (estimation
    part, outputs weighted 1/std as the fit) that the regressors ``G`` (n_est, ny, k) add to
    the sensitivities, and the regressors' coefficients in the joint least-squares fit."""
    k = G.shape[-1]
    Ge = (G * basis.w[None, :, None]).reshape(-1, k)
    if not np.all(np.isfinite(Ge)):
        return 0.0, 1.0, np.zeros(k)
    nrm = np.linalg.norm(Ge, axis=0)
    nrm[nrm == 0] = 1.0
    Gp = Ge / nrm
    Gp -= basis.Q @ (basis.Q.T @ Gp)              # what the sensitivities leave of G
    U, s, Vt = np.linalg.svd(Gp, full_matrices=False)
    keep = s > basis.tol
    beta = Vt[keep].T @ ((U[:, keep].T @ basis.r0) / s[keep]) / nrm
    e = basis.r0 - Gp @ (beta * nrm)
    sse1 = float(e @ e)
    share = max(0.0, (basis.sse0 - sse1) / (basis.ree or 1e-300))
    dof = max(basis.neff - (k + basis.q), 1.0)
    F = ((basis.sse0 - max(sse1, 1e-300)) / k) / (max(sse1, 1e-300) / dof)
    return share, float(stats.f.sf(max(F, 0.0), k, dof)), beta
