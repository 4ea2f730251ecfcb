"""The forward selection of one sub-model's diagnosis (:func:`rigd.diagnose.engine.
diagnose_data`): which effects are offered, each screened (signature, reveal, refit) on the
current model, the top significant one added, the rest screened again.

* :func:`offered` — the catalogue's effects for the sub-model, its domain, the record's length
  and what the base can carry (each omission in the notes);
* :func:`carried` — effects the base model already carries (named from it);
* :func:`screen` — the signature test and refit of each effect on one model;
* :class:`Selection` — the steps: add, refit, screen again; the input hold asked again once.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigd.diagnose import advice as A
from rigd.diagnose import domain as D
from rigd.diagnose import wording as W
from rigd.effects import REGISTRY
from rigd.effects.context import CannotReveal, Context, Finding
from rigd.ident.figures import fit_percent, refit_flag
from rigd.ident.model import base_of
from rigd.ident.thresholds import MIN_FIT_GAIN, MIN_REFIT_GAIN, P_LEVEL, STRONG_REFIT_GAIN


@dataclass
class Refit:
    structure: Any
    theta: np.ndarray
    yhat: np.ndarray
    fit_percent: float
    seconds: float
    #: parameters the refit kept at their start (``Effect.refit_fixed``)
    fixed: tuple[str, ...] = ()
    #: the signature the refit was started from (an effect's alternative form, or None)
    sig: Any = None
    #: (samples fitted, estimation samples) when the refit used a window of the estimation
    #: part (``Effect.max_fit_samples``), else None
    window: tuple[int, int] | None = None


@dataclass
class Step:
    """One forward-selection step: ``added`` effect (None: the base model) and its fit."""

    added: str | None
    fit_percent: float
    structure: Any
    theta: np.ndarray
    yhat: np.ndarray
    #: parameters its refit kept at their start; a refit of the step keeps them there too
    fixed: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return {"added": self.added, "fit_percent": round(float(self.fit_percent), 3)}


def fit_model(structure, data, theta0=None, max_nfev=None, fixed=None, method="oe"):
    """OE/PEM fit of ``structure`` on ``data`` (rigd.ident.pem.fit)."""
    from rigd.ident.pem import fit

    return fit(structure, data, method=method, theta0=theta0, max_nfev=max_nfev, fixed=fixed)


def val_err(ctx: Context, yhat: np.ndarray) -> float:
    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    e = (ctx.y[ctx.val] - yhat[ctx.val]) * w
    return float(np.sum(e ** 2))


def refit_effect(eff, ctx: Context, sig, data_est, max_nfev, method: str = "oe",
                 kept: tuple[str, ...] = ()) -> Refit:
    """Fit ``ctx.structure`` extended by ``eff``, warm-started from the signature
    (:func:`rigd.ident.pipeline.refit_with`, as ``rigd identify --add``); ``kept``: the
    parameters the earlier steps' refits kept at their start stay there (a curve's other
    sites). An effect that offers other forms of itself (``refit_alternatives(ctx, sig)``:
    a curve's state site beside its input or output site) has each refitted too; one is
    kept instead when it fits the held-out part better by ``MIN_FIT_GAIN`` points (its
    signature then in ``Refit.sig``). A form marked ``extra["refines"]`` (a second curve
    beside the first) is refitted only when the form kept so far gained ``MIN_FIT_GAIN``
    points on the model: on a large base each refit costs minutes. An effect with
    ``max_fit_samples`` below the estimation part's length is fitted on its first
    ``max_fit_samples`` samples (``Refit.window``)."""
    t0 = time.perf_counter()
    data_est, window = fit_window(eff, data_est)
    best = _refit_one(eff, ctx, sig, data_est, max_nfev, method, kept)
    fp0 = float(np.mean(fit_percent(ctx.y[ctx.val], ctx.yhat[ctx.val])))
    for alt in eff.refit_alternatives(ctx, sig):
        if alt.extra.get("refines") and best.fit_percent < fp0 + MIN_FIT_GAIN:
            continue  # a refinement of a form that did not matter: not worth its refit
        other = _refit_one(eff, ctx, alt, data_est, max_nfev, method, kept)
        if other.fit_percent >= best.fit_percent + MIN_FIT_GAIN:
            best = other
    best.seconds = time.perf_counter() - t0
    best.window = window
    return best


def fit_window(eff, data_est):
    """(data, window): ``data_est`` cut to the first ``eff.max_fit_samples`` samples when it
    is longer (window: (samples kept, samples given)), else ``(data_est, None)``."""
    cap, n = eff.max_fit_samples, data_est.n
    if cap is None or n <= cap:
        return data_est, None
    return data_est.slice(0, cap), (int(cap), int(n))


def window_note(name: str, cap: int, n_est: int) -> str:
    """The note said wherever an effect is fitted on a window of the estimation part."""
    return (f"{name} fitted on the first {cap} of the {n_est} estimation samples (its fits "
            f"cost minutes on all of them; --est chooses the samples)")


def _refit_one(eff, ctx: Context, sig, data_est, max_nfev, method: str,
               kept: tuple[str, ...]) -> Refit:
    from rigd.ident.pipeline import refit_with

    structure, theta, data = ctx.structure, ctx.theta, ctx.data
    # an effect may offer several starts (loop shapes): the fit with the lowest estimation
    # cost is kept (never chosen on the validation part)
    starts = eff.refit_starts(ctx, sig)
    # parameters an effect keeps at their start in the refit (a redundant scale)
    fixed = list(kept) + list(eff.refit_fixed(eff.extend(structure), sig))
    fixed = fixed or None
    ext, best, th0, fixed = refit_with(structure, theta, [eff], data_est, method,
                                       starts=starts, fixed=fixed, max_nfev=max_nfev)
    try:
        th = best.theta if best is not None else th0
        yw = np.asarray(ext.simulate(th, data), float)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        try:
            th, yw = th0, np.asarray(ext.simulate(th0, data), float)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            # the extension cannot be simulated on this model at all (two effects each
            # with a state model of its own, rigd.effects.compose): it gains nothing,
            # nothing crashes
            th, yw = th0, ctx.yhat
    if not np.all(np.isfinite(yw)):
        th, yw = th0, ctx.yhat
    fw = float(np.mean(fit_percent(ctx.y[ctx.val], yw[ctx.val])))
    return Refit(ext, th, yw, fw, 0.0, fixed, sig)


def _words(eff, ctx: Context, sig) -> tuple[str, dict[str, Any]]:
    """The explanation and evidence of ``eff``'s signature: an effect that emits an
    evidence code (``evidence(ctx, sig) -> (code, numbers)``) is worded by
    :mod:`rigd.diagnose.wording` for the record's domain; the others still word their own."""
    coded = eff.evidence(ctx, sig)
    if coded is None:
        return eff.explain(ctx, sig)
    code, ev = coded
    text = W.explanation(eff.name, code, dict(ev, share=sig.score, fs=ctx.fs), ctx.domain)
    return text, dict(ev, code=code)


def _refitted_words(eff, ctx: Context, f: Finding, theta_e: np.ndarray) -> None:
    """An effect whose size is read better from its refit than from its first-order
    signature (``refitted_evidence(ctx, theta_e) -> numbers``, e.g. a delay) is reported
    and worded with the refit's numbers and share (the signature's kept as
    ``signature_*``)."""
    if not np.all(np.isfinite(theta_e)):
        return
    new = eff.refitted_evidence(ctx, theta_e)
    if not new:   # the signature's numbers stand
        return
    for k, v in new.items():
        if k in f.evidence:
            f.evidence[f"signature_{k}"] = f.evidence[k]
        f.evidence[k] = v
    ev = {k: v for k, v in f.evidence.items() if k != "code"}
    f.explanation = W.explanation(eff.name, f.evidence["code"],
                                  dict(ev, share=f.score, fs=ctx.fs), ctx.domain)


def screen(ctx: Context, names: list[str], refit: bool, data_est, max_nfev,
            cannot: list[CannotReveal] | None, method: str = "oe",
            kept: tuple[str, ...] = (), memo=None) -> tuple[list[Finding], dict[str, Refit]]:
    """Signature test (and refit) of each effect in ``names`` on the model of ``ctx``
    (``kept``: parameters every refit keeps at their start, :func:`refit_effect`; ``memo``:
    refits done before on the same model, rigd.diagnose.memo).

    ``score`` is the share of *this* model's validation error energy the effect removes;
    effects the record cannot reveal go to ``cannot`` (when given) and are skipped.
    """
    findings, refits = [], {}
    err = val_err(ctx, ctx.yhat)
    fp = float(np.mean(fit_percent(ctx.y[ctx.val], ctx.yhat[ctx.val])))
    for name in names:
        eff = REGISTRY[name]
        if eff.not_offered(ctx.structure) is not None:  # listed by diagnose_data's notes
            continue
        why = eff.reveal(ctx)
        if why is not None and why.code is not None:  # worded for the record's domain
            why.why, why.experiment = A.cannot_reveal(
                name, why.code, dict(why.evidence, fs=ctx.fs,
                                     time_constants_s=ctx.time_constants_s), ctx.domain)
        if why is not None:
            if cannot is not None:
                why.submodel = ctx.submodel
                cannot.append(why)
            if not why.partial:  # a partial one (slow creep only) is still tested
                continue
        sig = eff.signature(ctx)
        text, ev = _words(eff, ctx, sig)
        sig_ok = sig.score >= eff.min_score and sig.f_p < P_LEVEL
        f = Finding(name, sig.score, False, text, ctx.submodel, sig.score, fp,
                    dict(ev, signature_p=sig.f_p, signature_k=sig.k))
        # an effect with a costly refit is refitted only when its signature's F test is
        # decisive (without it the effect cannot be significant: both rules below need it)
        # and the signature alone, in sample, is worth half the practical-significance gain
        # (a first-order signature underestimates a large effect: it is not asked for all)
        worth_refit = ((sig.f_p < P_LEVEL and (100.0 - fp) * (
            1.0 - np.sqrt(1.0 - min(max(sig.score_est, 0.0), 1.0))) >= MIN_FIT_GAIN / 2)
            if eff.costly_refit
            else sig.score > 0.005 or sig.f_p < P_LEVEL)
        if refit and worth_refit:
            ref = (refit_effect(eff, ctx, sig, data_est, max_nfev, method, kept)
                   if memo is None else
                   memo.refit(refit_effect, eff, ctx, sig, data_est, max_nfev, method, kept))
            refits[name] = ref
            if ref.sig is not None and ref.sig is not sig:  # another form of it fits
                sig = ref.sig
                text, ev = _words(eff, ctx, sig)
                f.explanation = text
                f.evidence = dict(ev, signature_p=sig.f_p, signature_k=sig.k)
            gain = max(0.0, 1.0 - val_err(ctx, ref.yhat) / err) if err > 0 else 0.0
            f.fit_percent_with = ref.fit_percent
            f.score = gain
            # a strong effect's first-order signature can be poor (a large cubic term
            # shifts the resonance; the base fit absorbs part of it): a decisive F test and
            # a refit that removes most of the error out of sample count as well
            strong = sig.f_p < P_LEVEL and gain >= STRONG_REFIT_GAIN
            # and it must matter at the scale of the output (practical significance)
            big = ref.fit_percent - fp >= MIN_FIT_GAIN
            f.significant = bool(((sig_ok and gain >= MIN_REFIT_GAIN) or strong) and big)
            f.evidence["refit_seconds"] = ref.seconds
            if ref.window is not None:
                f.evidence["fitted_on_samples"] = list(ref.window)
            flag = refit_flag(ref.fit_percent, fp)
            if flag is not None:  # a refit that lost fit or is below 0 %: never ranked
                f.evidence["refit_flag"] = flag
                f.significant = False
            theta_e = np.asarray(ref.theta)[len(ctx.theta):]
            _refitted_words(eff, ctx, f, theta_e)
            why_not = eff.implausible(ctx, theta_e)
            if why_not is not None:
                # it helps, but not as the physics its name says: unexplained, not named
                f.evidence["implausible"] = why_not
                f.significant = False
        else:
            f.evidence["refit"] = "not refitted: no signature in the residual"
        findings.append(f)
    findings.sort(key=lambda f: (not f.significant, "refit_flag" in f.evidence, -f.score,
                                 -f.signature_score))
    return findings, refits


def offered(effects: list[str] | None, submodel: str, dom, structure, est: slice, n: int,
             notes: list[str], data: Any = None) -> list[str]:
    """The effects to screen: ``effects`` as asked, else the catalogue's screened ones for
    ``submodel`` that the record's domain offers and the record's length affords; an effect
    the base cannot carry is left out either way. Each omission is said in ``notes``.

    ``data`` (the record): on a record that is not the rotor's, an effect locked to a
    rotating part's angle (``requires`` ``rotation``: run-out) is not offered when the
    record carries no angle — a structure under a shaker has nothing that turns, and
    advice to record an angle would be a rotor's. (On the rotor's records the missing
    encoder angle stays a "cannot tell" with the experiment that would show it.)"""
    names = list(effects or [nm for nm, e in REGISTRY.items()
                             if submodel in e.submodels and e.screened])
    if not effects:  # effects this domain cannot carry are not offered (not named either)
        kept = [nm for nm in names if D.offered(REGISTRY[nm], dom)]
        if len(kept) < len(names):
            notes.append(f"effects of mechanical structures or rotating parts are not tested "
                         f"on a {dom.name} record")
        names = kept
    rotor = dom.rotor
    for nm in list(names):  # an effect the base cannot carry is not offered, and says why
        why_not = REGISTRY[nm].not_offered(structure, None if rotor else data)
        if why_not is not None:
            names.remove(nm)
            notes.append(f"{nm} not offered: {why_not}")
    n_est = (est.stop or n) - (est.start or 0)
    for nm in names:  # a costly effect is fitted on a window of a long record: said so
        cap = REGISTRY[nm].max_fit_samples
        if cap is not None and n_est > cap:
            notes.append(window_note(nm, cap, n_est))
    return names


def carried(ctx0: Context, names: list[str], dom,
            worth: dict[str, float] | None = None) -> list[Finding]:
    """Findings of the effects the base model already carries, worded for the domain.

    ``worth``: per effect, the held-out fit points the base loses when refitted without it
    (:func:`rigd.ident.lti.delay_worth.delay_worth` for ``delay``); one that costs less than
    ``MIN_FIT_GAIN`` is listed but not significant (evidence code ``<code>_not_paid``): the
    data do not pay for it, the base could do without it."""
    carried = [f for f in (REGISTRY[nm].carried_by_base(ctx0) for nm in names) if f is not None]
    for f in carried:
        pts = (worth or {}).get(f.effect)
        if pts is not None:
            f.evidence["fit_points_lost"] = round(float(pts), 3)
            f.evidence["min_points"] = MIN_FIT_GAIN
            if pts < MIN_FIT_GAIN:
                f.significant = False
                f.evidence["code"] += "_not_paid"
        f.explanation = W.explanation(f.effect, f.evidence["code"],
                                      dict(f.evidence, share=0.0, fs=ctx0.fs), dom.name)
    return carried


class Selection:
    """The forward selection of :func:`diagnose_data` from the base model's context: add
    the top significant effect, refit, screen the rest again; ``steps`` and ``notes`` grow,
    ``refits`` keeps each added effect's refit, ``round_refits`` the last round's."""

    def __init__(self, ctx0: Context, context, refit: bool, data_est, max_nfev, method: str,
                 max_steps: int, other_hold: str | None, steps: list, notes: list[str],
                 memo=None):
        self.ctx0, self.context, self.refit = ctx0, context, refit
        self.memo = memo
        self.data_est, self.max_nfev, self.method = data_est, max_nfev, method
        self.max_steps, self.other_hold = max_steps, other_hold
        self.steps, self.notes = steps, notes
        self.refits: dict[str, Refit] = {}
        self.round_refits: dict[str, Refit] = {}

    def run(self, names: list[str], cannot: list[CannotReveal]
            ) -> tuple[list[Finding], list[Finding], float]:
        """(added, remaining findings on the final model, its validation error energy)."""
        ctx, err_base = self.ctx0, val_err(self.ctx0, self.ctx0.yhat)
        findings, self.round_refits = screen(ctx, names, self.refit, self.data_est,
                                              self.max_nfev, cannot, self.method,
                                              memo=self.memo)
        revealable = [f.effect for f in findings]
        added: list[Finding] = []
        while True:
            err_cur = val_err(ctx, ctx.yhat)
            top = findings[0] if findings and findings[0].significant else None
            if top is None or not self.refit or len(added) >= self.max_steps:
                break
            step = self._add(ctx, top, added, err_cur, err_base)
            ctx = self.context(step.structure, step.theta, step.yhat)
            rest = [nm for nm in revealable if nm not in {f.effect for f in added}]
            if not rest:
                findings = []
                break
            findings, self.round_refits = screen(ctx, rest, self.refit, self.data_est,
                                                  self.max_nfev, None, self.method,
                                                  step.fixed, self.memo)
        return added, findings, err_cur

    def _add(self, ctx: Context, top: Finding, added: list[Finding], err_cur: float,
             err_base: float) -> Step:
        """Add ``top`` (its refit of this round) as the next step; the other hold is tried
        once (``other_hold``) and kept when it fits better."""
        ref = self.round_refits[top.effect]
        err_new = val_err(ctx, ref.yhat)
        top.score = (err_cur - err_new) / err_base if err_base > 0 else 0.0
        if added:
            top.explanation = (f"with {', '.join(f.effect for f in added)} added: "
                               f"{top.explanation}")
            top.evidence["found_after"] = [f.effect for f in added]
        top.evidence["step"] = len(added) + 1
        added.append(top)
        step = Step(top.effect, ref.fit_percent, ref.structure, ref.theta, ref.yhat,
                    ref.fixed)
        hold = self.other_hold
        alt = None
        if hold and self.memo is not None:
            alt = self.memo.try_hold(try_hold, step, self.ctx0, hold, self.data_est,
                                     self.method)
        elif hold:
            alt = try_hold(step, self.ctx0, hold, self.data_est, self.method)
        if alt is not None:
            self.notes.append(f"inputs between samples: with {top.effect} in the model, "
                              f"{hold} fits {alt.fit_percent:.2f} % against "
                              f"{step.fit_percent:.2f} % (the hold was chosen by the linear "
                              f"base model): {hold} from this step on (rigd identify --hold "
                              f"{hold})")
            top.evidence["hold"] = hold
            top.fit_percent_with = alt.fit_percent
            top.score = ((err_cur - val_err(ctx, alt.yhat)) / err_base if err_base > 0
                         else 0.0)
            ref = Refit(alt.structure, alt.theta, alt.yhat, alt.fit_percent, ref.seconds,
                        alt.fixed)
            step, self.other_hold = alt, None
        self.refits[top.effect] = ref
        self.steps.append(step)
        return step


def other_hold(bf) -> str | None:
    """The hold the forward selection asks again once an effect is in (:func:`try_hold`):
    the other of zoh/foh when the linear base chose ``bf``'s hold from the data
    (rigd.ident.pipeline.BaseFit), else None (declared by the record or asked)."""
    return {"zoh": "foh", "foh": "zoh"}[bf.hold.hold] if bf.hold.source == "fit" else None


def try_hold(step: Step, ctx0: Context, hold: str, data_est,
              method: str = "oe") -> Step | None:
    """``step``'s model refitted with the input hold ``hold``, if that fits the validation
    part better by ≥ ``MIN_FIT_GAIN`` points, else None.

    For records whose hold was chosen from the data by the *linear* base model: an
    unmodelled nonlinearity can favour a half-sample lag (the Bouc–Wen benchmark's smooth
    multisine: zoh by 1.7 points for the linear model, foh by ≈ 8 once the hysteresis is
    in), so once an effect is in the model the question is asked again.
    """
    st = copy.deepcopy(step.structure)
    base_of(st).hold = hold  # the hold lives on the base (a composed model reads it)
    fixed = list(step.fixed) or None  # what the step's own refit kept (a curve's sites)
    try:
        th = fit_model(st, data_est, theta0=step.theta, fixed=fixed, method=method).theta
        yh = np.asarray(st.simulate(th, ctx0.data), float)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return None
    if not np.all(np.isfinite(yh)):
        return None
    fp = float(np.mean(fit_percent(ctx0.y[ctx0.val], yh[ctx0.val])))
    return (Step(step.added, fp, st, th, yh, step.fixed)
            if fp >= step.fit_percent + MIN_FIT_GAIN else None)
