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
of sample. Used by ``friction`` (promoted from the dry-friction probe) and
``static_nonlinearity``.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from rigd.effects.context import Context
from rigd.effects.detectability import parameter_responses
from rigd.effects.signature import SignatureFit, effective_n


def joint_signature(ctx: Context, regs: list[np.ndarray]) -> SignatureFit:
    """The linearised refit of the regressors ``regs`` (each (n, ny)) on ``ctx``: share and
    F test beyond the base model's sensitivities, ``beta`` the regressors' coefficients
    (score = score_est = the in-sample share)."""
    J = sensitivities(ctx)
    if J is None or not regs:
        return SignatureFit(0.0, np.zeros(len(regs)), 1.0, len(regs))
    share, p, beta = joint_share(ctx, np.stack(regs, axis=-1), J)
    return SignatureFit(share, beta[:len(regs)], p, len(regs), share)


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


def joint_share(ctx: Context, G: np.ndarray, J: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(share, F-test p, coefficients): the share of the base residual's energy (estimation
    part, outputs weighted 1/std as the fit) that the regressors ``G`` (n, ny, k) add to the
    sensitivities ``J`` (n, ny, q), and the joint least-squares coefficients [G, J]."""
    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    re = (ctx.residual[ctx.est] * w).reshape(-1)
    X = np.concatenate([G, J], axis=-1)[ctx.est] * w[None, :, None]
    k, q = G.shape[-1], X.shape[-1]
    Xe = X.reshape(-1, q)
    if not np.all(np.isfinite(Xe)):
        return 0.0, 1.0, np.zeros(q)
    nrm = np.linalg.norm(Xe, axis=0)
    nrm[nrm == 0] = 1.0
    fits = []
    for cols in (slice(0, q), slice(k, q)):        # with the forces, and without
        b = np.linalg.lstsq(Xe[:, cols] / nrm[cols], re, rcond=None)[0] / nrm[cols]
        e = re - Xe[:, cols] @ b
        fits.append((float(e @ e), b))
    (sse1, beta), (sse0, _) = fits
    share = max(0.0, (sse0 - sse1) / (float(re @ re) or 1e-300))
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - q, 1.0)
    F = ((sse0 - max(sse1, 1e-300)) / k) / (max(sse1, 1e-300) / dof)
    return share, float(stats.f.sf(max(F, 0.0), k, dof)), beta
