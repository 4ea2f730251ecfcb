"""Can this record tell an effect? Predict its signature at a plausible size and test it.

An effect's ``reveal`` asks: if the effect were present at a nominal, physically plausible
size (each effect states its own, relative to the record's signals, e.g. a creep of 5 % of the
step, a hysteresis loop 5 % of the input range), would the diagnosis see it on *this* record's
own input? The answer uses the machinery of the findings (rigd.effects.signature):

1. the predicted signature s (n, ny): the output change the effect would make, simulated
   through the fitted base model on the recorded input;
2. the part a refit of the base model alone would absorb is removed: s is projected off the
   base model's sensitivity space J = ∂ŷ/∂θ (finite differences over its parameters) and off
   a constant per output (the prefilters remove offsets). A hysteresis under a two-level input
   is a gain change, so it lies in that space and nothing is left;
3. what is left, s⊥, is compared with the residual level by the findings' rules
   (rigd.diagnose.engine): the F test, expected F = (‖s⊥‖²/k) / (‖r‖²/(n_eff − k)) on the
   estimation part, outputs weighted 1/std(y), k the number of the effect's signature
   parameters, n_eff the residual's effective sample size (autocorrelation-corrected,
   rigd.effects.signature.effective_n), p below P_LEVEL = 1e-3; the share of the error
   energy it would carry, ‖s⊥‖²/(‖r‖² + ‖s⊥‖²) ≥ MIN_REFIT_GAIN (10 %); and the fit points
   its removal would add ≥ MIN_FIT_GAIN (0.5). Statistically visible but practically too
   small (a sub-0.5-point change) is what the findings would not name either.

A record whose residual already carries the effect's signature (by the same rules,
:func:`seen`) can tell it whatever the prediction says: a strong effect makes the
residual large and autocorrelated, which would mask a nominal-size one.

So "cannot tell X" is said only when X at a plausible size would stay undetectable; the
structural impossibilities (no shaft angle, a single axis) stay rules in the effects.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigd.effects.context import Context
from rigd.effects.signature import effective_n
from rigd.ident.thresholds import MIN_FIT_GAIN, MIN_REFIT_GAIN, P_LEVEL

#: relative finite-difference step of the base model's sensitivities
_STEP = 1e-4


def _rules() -> tuple[float, float]:
    return MIN_REFIT_GAIN, MIN_FIT_GAIN


@dataclass
class Detectability:
    """How well a predicted signature would show against the residual.

    Attributes
    ----------
    p : float
        p-value of the findings' F test for the predicted signature (1: nothing left).
    snr : float
        rms of the unabsorbable part s⊥ over the rms of the residual (estimation part,
        weighted outputs).
    absorbed : float
        Share (0..1) of the predicted signature's energy the base model (and an offset)
        would take up.
    fit_gain : float
        Validation-fit points (mean over outputs) its removal would add.
    """

    p: float
    snr: float
    absorbed: float
    fit_gain: float = 0.0

    @property
    def share(self) -> float:
        """Share of the error energy the predicted signature would carry."""
        return self.snr ** 2 / (1.0 + self.snr ** 2)

    @property
    def detectable(self) -> bool:
        min_share, min_points = _rules()
        return bool(self.p < P_LEVEL and self.share >= min_share
                    and self.fit_gain >= min_points)

    def describe(self) -> str:
        """Short evidence text: absorbed share, size against the residual, fit points, p."""
        return (f"{100 * self.absorbed:.3g} % of it would be absorbed by the base model; the "
                f"rest is {self.snr:.2g}× the residual level, {self.fit_gain:.2g} fit points, "
                f"F test p = {self.p:.2g}")


def _weights(ctx: Context) -> np.ndarray:
    s = np.std(ctx.y[ctx.est], axis=0)
    s[s == 0] = 1.0
    return 1.0 / s


def parameter_responses(ctx: Context) -> list[tuple[int, float, np.ndarray | None]]:
    """The base model simulated over the whole record with each parameter stepped in turn:
    [(index, step h, output (n, ny) or None if that simulation failed)] (cached; shared by
    :func:`tangent` and the friction signature of rigd.effects.friction)."""
    cache = ctx.cache
    if "parameter_responses" in cache:
        return cache["parameter_responses"]
    from rigd.ident.pem import _scale  # typical parameter sizes of the structure

    theta = np.asarray(ctx.theta, float)
    try:
        scale = np.asarray(_scale(ctx.structure, theta), float)
    except Exception:  # noqa: BLE001 - a foreign structure: relative steps
        scale = np.maximum(np.abs(theta), 1e-6)
    out = []
    for i in range(theta.size):
        h = _STEP * max(abs(theta[i]), scale[i], 1e-12)
        th = theta.copy()
        th[i] += h
        try:
            yi = np.asarray(ctx.structure.simulate(th, ctx.data), float)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            yi = None
        out.append((i, h, yi))
    cache["parameter_responses"] = out
    return out


def tangent(ctx: Context) -> np.ndarray:
    """(n_est·ny, p + ny) weighted sensitivities of the base model's simulation to its
    parameters on the estimation part, plus one constant column per output (cached)."""
    cache = ctx.cache
    if "tangent" in cache:
        return cache["tangent"]
    w = _weights(ctx)
    y0 = np.asarray(ctx.yhat, float)[ctx.est] * w
    cols = []
    for _, h, yfull in parameter_responses(ctx):
        if yfull is None:
            continue
        yi = yfull[ctx.est] * w
        d = (yi - y0) / h
        if np.all(np.isfinite(d)) and np.any(d):
            cols.append(d.reshape(-1))
    n = y0.shape[0]
    for i in range(ctx.ny):
        c = np.zeros((n, ctx.ny))
        c[:, i] = 1.0
        cols.append(c.reshape(-1))
    J = np.stack(cols, axis=1)
    # orthonormal basis (drop directions the parameters do not move)
    U, sv, _ = np.linalg.svd(J / np.maximum(np.linalg.norm(J, axis=0), 1e-300),
                             full_matrices=False)
    Q = U[:, sv > 1e-8 * sv[0]]
    cache["tangent"] = Q
    return Q


def detectability(ctx: Context, s: np.ndarray, k: int = 1,
                   nuisance=()) -> Detectability:
    """Would the predicted signature ``s`` (n, ny) show against the residual of ``ctx``?

    ``k``: number of parameters the effect's signature regression fits (the findings'
    F test uses the same). ``nuisance``: further (n, ny) directions the effect's own free
    parameters would take up without being the effect (e.g. creep's initial-state decays),
    removed like the base model's.
    """
    s = np.asarray(s, float)
    if s.ndim == 1:
        s = s[:, None]
    w = _weights(ctx)
    se = (s[ctx.est] * w).reshape(-1)
    if not np.all(np.isfinite(se)) or not np.any(se):
        return Detectability(1.0, 0.0, 1.0)
    Q = tangent(ctx)
    sp = se - Q @ (Q.T @ se)
    extra = [(np.asarray(g, float)[ctx.est] * w).reshape(-1) for g in nuisance]
    extra = [g - Q @ (Q.T @ g) for g in extra if np.all(np.isfinite(g)) and np.any(g)]
    if extra:
        Z = np.stack(extra, axis=1)
        sp = sp - Z @ np.linalg.lstsq(Z, sp, rcond=None)[0]
    e_s, e_p = float(se @ se), float(sp @ sp)
    absorbed = 1.0 - e_p / e_s if e_s > 0 else 1.0
    r = (ctx.residual[ctx.est] * w).reshape(-1)
    ss_r = max(float(r @ r), 1e-300)
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - k, 1.0)
    from scipy import stats

    F = (e_p / k) / (ss_r / dof)
    p = float(stats.f.sf(max(F, 0.0), k, dof))
    snr = float(np.sqrt(e_p / ss_r))
    # fit points per output: 100 (‖r + s⊥‖ − ‖r‖) / ‖y − ȳ‖, with ‖r + s⊥‖² ≈ ‖r‖² + ‖s⊥‖²
    ny = ctx.ny
    sp_i = np.sum(sp.reshape(-1, ny) ** 2, axis=0)
    r_i = np.sum(r.reshape(-1, ny) ** 2, axis=0)
    ye = ctx.y[ctx.est] * w
    dy = np.maximum(np.sqrt(np.sum((ye - ye.mean(axis=0)) ** 2, axis=0)), 1e-300)
    gain = float(np.mean(100.0 * (np.sqrt(r_i + sp_i) - np.sqrt(r_i)) / dy))
    return Detectability(p, snr, float(np.clip(absorbed, 0.0, 1.0)), gain)


def best(ctx: Context, signatures, k: int = 1, nuisance=None) -> tuple[Detectability, int]:
    """The most detectable of several predicted signatures (e.g. over time constants) and
    its index; ``nuisance``: one list of nuisance directions per signature."""
    nuisance = nuisance or [()] * len(signatures)
    out = [detectability(ctx, s, k, z) for s, z in zip(signatures, nuisance)]
    i = max(range(len(out)), key=lambda j: (out[j].detectable, out[j].fit_gain))
    return out[i], i


def seen(ctx: Context, sig) -> bool:
    """True when the effect's signature on the actual residual already passes the same rules
    (F test p < P_LEVEL, share of the validation error energy ≥ MIN_REFIT_GAIN, fit points
    ≥ MIN_FIT_GAIN): the record shows it."""
    min_share, min_points = _rules()
    y, yh = ctx.y[ctx.val], ctx.yhat[ctx.val]
    dy = np.maximum(np.linalg.norm(y - y.mean(axis=0), axis=0), 1e-300)
    err = float(np.mean(100.0 * np.linalg.norm(y - yh, axis=0) / dy))
    gain = err * (1.0 - np.sqrt(max(1.0 - float(sig.score), 0.0)))
    return bool(sig.f_p < P_LEVEL and sig.score >= min_share and gain >= min_points)
