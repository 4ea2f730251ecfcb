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

#: least share of the final residual a probe must explain to be reported
MIN_SHARE = 0.10
#: sgn(v) is smoothed as tanh(v / v_ε), v_ε this fraction of the rms velocity
SMOOTH = 0.05
#: finite-difference step of the sensitivities, relative to the parameter's scale
STEP = 1e-4


def _velocity_sign(p: np.ndarray, fs: float) -> np.ndarray | None:
    v = np.gradient(np.asarray(p, float)) * fs
    rms = float(np.sqrt(np.mean(v * v)))
    if not np.isfinite(rms) or rms <= 0:
        return None
    return np.tanh(v / (SMOOTH * rms))


def sensitivities(ctx: Context) -> np.ndarray | None:
    """(n, ny, p + ny) of ∂ŷ/∂θ of the base model over the whole record (finite differences
    at the fit's parameter scale) and one constant column per output; None if a simulation
    fails. Cached in ``ctx.cache``."""
    if "probe_sensitivities" in ctx.cache:
        return ctx.cache["probe_sensitivities"]
    from rigd.ident.pem import _scale

    theta = np.asarray(ctx.theta, float)
    y0 = np.asarray(ctx.yhat, float)
    try:
        scale = np.asarray(_scale(ctx.structure, theta), float)
    except Exception:  # noqa: BLE001 - a foreign structure: relative steps
        scale = np.maximum(np.abs(theta), 1e-6)
    cols, which = [], []
    for i in range(theta.size):
        h = STEP * max(abs(theta[i]), scale[i], 1e-12)
        th = theta.copy()
        th[i] += h
        try:
            yi = np.asarray(ctx.structure.simulate(th, ctx.data), float)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            return None
        d = (yi - y0) / h
        if np.all(np.isfinite(d)) and np.any(d):
            cols.append(d)
            which.append(i)
    for i in range(ctx.ny):
        c = np.zeros_like(y0)
        c[:, i] = 1.0
        cols.append(c)
    J = np.stack(cols, axis=-1)
    ctx.cache["probe_sensitivities"] = J
    ctx.cache["probe_parameters"] = which     # the parameter of each column (then constants)
    return J


def joint_share(ctx: Context, g: np.ndarray, J: np.ndarray) -> tuple[float, float, float]:
    """(validation share, estimation share, F-test p) that the regressor ``g`` (n, ny) adds
    to the sensitivities ``J`` (n, ny, q) in explaining the base residual (weighted per
    output as the fit)."""
    from scipy import stats

    from rigd.effects.signature import effective_n

    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    r = ctx.residual * w
    X = np.concatenate([np.asarray(g, float)[..., None], J], axis=-1) * w[None, :, None]
    q = X.shape[-1]
    re, rv = r[ctx.est].reshape(-1), r[ctx.val].reshape(-1)
    Xe, Xv = X[ctx.est].reshape(-1, q), X[ctx.val].reshape(-1, q)
    if not (np.all(np.isfinite(Xe)) and np.all(np.isfinite(Xv))):
        return 0.0, 0.0, 1.0
    nrm = np.linalg.norm(Xe, axis=0)
    nrm[nrm == 0] = 1.0
    out = []
    for cols in (slice(0, q), slice(1, q)):        # with the force, and without
        A = Xe[:, cols] / nrm[cols]
        b = np.linalg.lstsq(A, re, rcond=None)[0] / nrm[cols]
        out.append((re - Xe[:, cols] @ b, rv - Xv[:, cols] @ b))
    (ee1, ev1), (ee0, ev0) = out
    s0v, s0e = float(rv @ rv) or 1e-300, float(re @ re) or 1e-300
    share_v = max(0.0, (float(ev0 @ ev0) - float(ev1 @ ev1)) / s0v)
    share_e = max(0.0, (float(ee0 @ ee0) - float(ee1 @ ee1)) / s0e)
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - q, 1.0)
    sse1 = max(float(ee1 @ ee1), 1e-300)
    F = (float(ee0 @ ee0) - sse1) / (sse1 / dof)
    return share_v, share_e, float(stats.f.sf(max(F, 0.0), 1, dof))


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
    J = sensitivities(ctx)
    if J is None:
        return None
    best = None
    for i in range(ctx.ny):
        s = _velocity_sign(ctx.yhat[:, i], ctx.fs)
        if s is None:
            continue
        # a motion that never reverses cannot tell a friction force from an offset
        if min(np.mean(s > 0.5), np.mean(s < -0.5)) < 0.1:
            continue
        g = ctx.through_force(s, i)
        _, share, p = joint_share(ctx, g, J)
        if share >= MIN_SHARE and p < p_level and (best is None or share > best[1]):
            best = (i, share, g, s)
    if best is None:
        return None
    i, share, g, s = best
    # its size: the force alone on the residual with the parameters re-adjusted (the
    # coefficient of g in the joint fit, acceleration units), in units of the input that
    # drives output i most
    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    X = np.concatenate([g[..., None], J], axis=-1)[ctx.est] * w[None, :, None]
    beta = np.linalg.lstsq(X.reshape(-1, X.shape[-1]),
                           (ctx.residual[ctx.est] * w).reshape(-1), rcond=None)[0]
    fc = -float(beta[0])              # > 0: opposes the motion
    out = ctx.label(i)
    # the input gain after the same joint step (the base's own gain is biased by the force
    # it absorbed: on the stage, 30 % low)
    theta = np.array(ctx.theta, float)
    for col, k in enumerate(ctx.cache.get("probe_parameters", [])):
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
