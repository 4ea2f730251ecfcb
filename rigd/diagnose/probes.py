"""Probes for physics outside the catalogue: they describe *unexplained* structure, never name
a finding (``../shared/DESIGN.md``: what matches nothing in the catalogue is reported as such).

A probe is a *linearised refit* of the base model with one force the catalogue lacks: the
base model's residual regressed on the model's response to that force together with the
model's own sensitivities ∂ŷ/∂θ (one simulation per parameter) and a constant per output —
on the estimation part: the share of the residual the force adds to the sensitivities alone,
with an F test on an autocorrelation-corrected sample size. In-sample, because a strong force
moves the linear parameters further than a first-order step extrapolates (on the stage below
the joint step found the friction to 5 %, and predicted the validation part worse than
nothing); the F test and the share threshold guard against chance, and the text says that the
refit behind it is linearised. The sensitivities matter: a linear
fit absorbs much of a strong nonlinear force into wrong linear parameters (on a positioning
stage with dry friction, a spring and too much damping), so the residual alone barely
correlates with the force's response (0.3 %) while the joint refit explains most of it.
It is reported when it explains at least :data:`MIN_SHARE` of the residual with
p < :data:`rigd.diagnose.engine.P_LEVEL`.

* :func:`dry_friction` — a force of constant size that opposes the motion of a degree of
  freedom, −F_c·sgn(ṗ_i) (Coulomb friction in a guide, a bearing, a seal; the known missing
  effect of an electro-mechanical positioning stage). sgn is smoothed over ±5 % of the rms
  velocity of the model's output (relative to the record: the same for any unit or rate).
  Generic records only: the rotor's gas film has no dry friction.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.effects import numbers as N
from rigd.effects.context import Context
from rigd.effects.detectability import parameter_responses
from rigd.ident.thresholds import MIN_SHARE

#: sgn(v) is smoothed as tanh(v / v_ε), v_ε this fraction of the rms velocity
SMOOTH = 0.05


def _velocity_sign(p: np.ndarray, fs: float) -> np.ndarray | None:
    v = np.gradient(np.asarray(p, float)) * fs
    rms = float(np.sqrt(np.mean(v * v)))
    if not np.isfinite(rms) or rms <= 0:
        return None
    return np.tanh(v / (SMOOTH * rms))


def sensitivities(ctx: Context) -> tuple[np.ndarray, list[int]] | None:
    """(J, parameters): ∂ŷ/∂θ of the base model over the whole record, (n, ny, q), from the
    stepped simulations of :func:`rigd.effects.detectability.parameter_responses` (the
    parameters that move the output, their indices in ``parameters``) and one constant column
    per output; None if a stepped simulation failed."""
    y0 = np.asarray(ctx.yhat, float)
    cols, which = [], []
    for i, h, yi in parameter_responses(ctx):
        if yi is None:
            return None
        d = (yi - y0) / h
        if np.all(np.isfinite(d)) and np.any(d):
            cols.append(d)
            which.append(i)
    for i in range(ctx.ny):
        c = np.zeros_like(y0)
        c[:, i] = 1.0
        cols.append(c)
    return np.stack(cols, axis=-1), which


def joint_share(ctx: Context, g: np.ndarray, J: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(share, F-test p, coefficients): the share of the base residual's energy (estimation
    part, weighted per output as the fit) that the regressor ``g`` (n, ny) adds to the
    sensitivities ``J`` (n, ny, q), and the joint least-squares coefficients [g, J...]."""
    from scipy import stats

    from rigd.effects.signature import effective_n

    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    re = (ctx.residual[ctx.est] * w).reshape(-1)
    X = np.concatenate([np.asarray(g, float)[..., None], J], axis=-1)[ctx.est] * w[None, :, None]
    q = X.shape[-1]
    Xe = X.reshape(-1, q)
    if not np.all(np.isfinite(Xe)):
        return 0.0, 1.0, np.zeros(q)
    nrm = np.linalg.norm(Xe, axis=0)
    nrm[nrm == 0] = 1.0
    fits = []
    for cols in (slice(0, q), slice(1, q)):        # with the force, and without
        b = np.linalg.lstsq(Xe[:, cols] / nrm[cols], re, rcond=None)[0] / nrm[cols]
        e = re - Xe[:, cols] @ b
        fits.append((float(e @ e), b))
    (sse1, beta), (sse0, _) = fits
    share = max(0.0, (sse0 - sse1) / (float(re @ re) or 1e-300))
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - q, 1.0)
    F = (sse0 - max(sse1, 1e-300)) / (max(sse1, 1e-300) / dof)
    return share, float(stats.f.sf(max(F, 0.0), 1, dof)), beta


def _gain_row(ctx: Context, theta: np.ndarray, i: int) -> np.ndarray:
    """Row i of the mass-normalised input gain B of the base model at ``theta``."""
    _, B, _, _, _ = ctx.structure.continuous(theta)
    return np.asarray(B, float)[np.asarray(B).shape[0] // 2 + i].copy()


def dry_friction(ctx: Context, p_level: float) -> dict[str, Any] | None:
    """Does the base model's residual hide a dry-friction force at one of its outputs?

    Parameters
    ----------
    ctx : Context
        The base model's context (its mechanical model carries the probe's force).
    p_level : float
        F-test level of the findings.

    Returns
    -------
    dict or None
        An ``unexplained`` entry (``where``, ``share``, ``suggests``, ``text``,
        ``friction``) for the output where the probe explains most, when it explains
        ≥ :data:`MIN_SHARE` significantly; None otherwise (and on rotor records).
    """
    if N.is_rotor(ctx) or not callable(getattr(ctx.structure, "continuous", None)):
        return None
    sens = sensitivities(ctx)
    if sens is None:
        return None
    J, which = sens
    best = None
    for i in range(ctx.ny):
        s = _velocity_sign(ctx.yhat[:, i], ctx.fs)
        if s is None:
            continue
        # a motion that never reverses cannot tell a friction force from an offset
        if min(np.mean(s > 0.5), np.mean(s < -0.5)) < 0.1:
            continue
        share, p, beta = joint_share(ctx, ctx.through_force(s, i), J)
        if share >= MIN_SHARE and p < p_level and (best is None or share > best[1]):
            best = (i, share, beta)
    if best is None:
        return None
    i, share, beta = best
    # its size: the coefficient of the force in the joint fit (acceleration units), in units
    # of the input that drives output i most
    fc = -float(beta[0])              # > 0: opposes the motion
    out = ctx.label(i)
    # the input gain after the same joint step (the base's own gain is biased by the force
    # it absorbed: on the stage, 30 % low)
    theta = np.array(ctx.theta, float)
    for col, k in enumerate(which):
        theta[k] += beta[1 + col]
    b = _gain_row(ctx, theta, i)
    b0 = _gain_row(ctx, ctx.theta, i)
    j = int(np.argmax(np.abs(b0)))
    if not (np.isfinite(b[j]) and b[j] * b0[j] > 0):    # the step flipped or lost it
        b = b0
    size = abs(fc / b[j]) if b[j] != 0 else float("nan")
    against = fc > 0
    sugg = ("dry (Coulomb) friction, outside the catalogue: a force of constant size that "
            "opposes the motion (a guide, a bearing, a seal); a slow triangle input at two "
            "speeds would confirm it (dry friction does not change with speed)"
            if against else
            "a force of constant size that changes sign with the direction of motion but "
            "drives it (not friction: a sign error, or a direction-dependent actuator), "
            "outside the catalogue; a slow triangle input would show it")
    inp = ctx.label(j, "in")
    text = (f"{N.share(share)} of the error energy goes with a force of constant size that "
            f"changes sign with the velocity of {out} ({'opposing' if against else 'along'} "
            f"the motion, about {size:.3g} in units of the input {inp}; a refit of the "
            f"linear model with it, linearised): {sugg}")
    return {"where": {"direction_of_motion": out},
            "share": round(float(share), 4), "suggests": sugg, "text": text,
            "friction": {"input": inp, "size_input_units": float(f"{size:.6g}"),
                         "opposes_motion": bool(against)}}
