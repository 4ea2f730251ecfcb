"""The diagnosis: fit the base model, test every catalogue effect, refit, rank, report.

For one sub-model (``actuator`` r→u, ``bearing`` u→e, ``generic``):

1. fit the base grey-box structure by output error on the estimation part and simulate the
   whole record; the residual is measurement − simulation;
2. for every effect of the catalogue that concerns the sub-model: ``reveal`` (can this record
   show it? if not: why, and which experiment would) and the signature regression (share of
   the validation residual energy its first-order signature explains, F test);
3. refit the base structure extended by each revealable effect (warm-started from the
   signature) and measure the validation fit; ``score`` = share of the base model's
   validation error energy the effect removes;
4. an effect is *significant* when its signature is (share ≥ its ``min_score``, p < 1e-3)
   and its refit lowers the validation error energy by at least ``MIN_REFIT_GAIN``;
5. when the residual of the best model is still structured (whiteness or residual–input
   correlation fails, or it is above the noise estimate), it is reported as *unexplained*
   with where it lives (frequency bands, amplitude, time, direction of input motion), its
   share of the error energy and what it suggests (:mod:`rigd.diagnose.unexplained`).

This module is the per-data stepwise engine (:func:`diagnose_data`); whole records (sub-models,
window, split, input hold) are diagnosed by :func:`rigd.diagnose.diagnosis.diagnose_record`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.diagnose import advice as A
from rigd.diagnose import domain as D
from rigd.diagnose import residual as R
from rigd.diagnose import unexplained as U
from rigd.diagnose import wording as W
from rigd.effects import REGISTRY
from rigd.effects.context import CannotReveal, Context, Finding
from rigd.ident.figures import fit_percent
from rigd.ident.mechanical import DEFAULT_HOLD, structure_for
from rigd.ident.thresholds import MIN_FIT_GAIN, MIN_REFIT_GAIN, P_LEVEL, STRONG_REFIT_GAIN

#: most effects added by the forward selection
MAX_STEPS = 3


@dataclass
class Refit:
    structure: Any
    theta: np.ndarray
    yhat: np.ndarray
    fit_percent: float
    seconds: float


@dataclass
class Step:
    """One forward-selection step: ``added`` effect (None: the base model) and its fit."""

    added: str | None
    fit_percent: float
    structure: Any
    theta: np.ndarray
    yhat: np.ndarray

    def to_json(self) -> dict[str, Any]:
        return {"added": self.added, "fit_percent": round(float(self.fit_percent), 3)}


@dataclass
class SubDiagnosis:
    """Diagnosis of one sub-model.

    ``ctx`` is the base model's context (its residual is what the report shows as "where it
    fails"); ``steps`` the forward selection (base first, then each added effect with the
    validation fit of the model extended by it and every effect before it).
    """

    submodel: str
    fit_percent: float
    findings: list[Finding]
    cannot_reveal: list[CannotReveal]
    unexplained: list[dict]
    ctx: Context
    tests: dict[str, Any] = field(default_factory=dict)
    refits: dict[str, Refit] = field(default_factory=dict)
    window: tuple[int, int] = (0, 0)
    steps: list[Step] = field(default_factory=list)
    #: the base model's number of modes and how it was chosen (generic records)
    order: dict[str, Any] | None = None
    #: what the engine decided along the way (e.g. the input hold asked again)
    notes: list[str] = field(default_factory=list)
    #: what a plain ARX and a subspace model reach on the same split
    #: (:class:`rigd.ident.yardstick.Yardstick`, ``model_fit`` = the base model's fit)
    yardstick: Any = None
    #: the record's domain (rigd.diagnose.domain): the words and the advice
    domain: Any = None
    #: how the base model was fitted (rigd.ident.pipeline.BaseFit.to_json)
    base: dict[str, Any] | None = None

    @property
    def final(self) -> Step:
        """The model after the last forward-selection step."""
        return self.steps[-1]


def _fit(structure, data, theta0=None, max_nfev=None, fixed=None, method="oe"):
    from rigd.ident.pem import fit

    return fit(structure, data, method=method, theta0=theta0, max_nfev=max_nfev, fixed=fixed)


def model_resonances(structure, theta) -> list[float]:
    """Resonance frequencies (Hz) of the base model's linear part (rigd.ident.readouts)."""
    from rigd.ident.model import linear_part_of
    from rigd.ident.readouts import resonances_hz

    lp = linear_part_of(structure, theta)
    if lp is None or not np.all(np.isfinite(lp.A)):
        return []
    return sorted({round(f, 3) for f in resonances_hz(lp)})


def _val_err(ctx: Context, yhat: np.ndarray) -> float:
    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    e = (ctx.y[ctx.val] - yhat[ctx.val]) * w
    return float(np.sum(e ** 2))


def _refit(eff, ctx: Context, sig, data_est, max_nfev, method: str = "oe") -> Refit:
    """Fit ``ctx.structure`` extended by ``eff``, warm-started from the signature
    (:func:`rigd.ident.pipeline.refit_with`, as ``rigd identify --add``)."""
    from rigd.ident.pipeline import refit_with

    t0 = time.perf_counter()
    structure, theta, data = ctx.structure, ctx.theta, ctx.data
    # an effect may offer several starts (loop shapes): the fit with the lowest estimation
    # cost is kept (never chosen on the validation part)
    starts = (eff.refit_starts(ctx, sig) if hasattr(eff, "refit_starts")
              else [eff.warm_start(ctx, sig)])
    # parameters an effect keeps at their start in the refit (a redundant scale)
    fixed = list(getattr(eff, "refit_fixed", lambda e, s=None: [])(eff.extend(structure),
                                                                    sig)) or None
    ext, best, th0 = refit_with(structure, theta, [eff], data_est, method, starts=starts,
                                fixed=fixed, max_nfev=max_nfev)
    try:
        th = best.theta if best is not None else th0
        yw = np.asarray(ext.simulate(th, data), float)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        try:
            th, yw = th0, np.asarray(ext.simulate(th0, data), float)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            # the extension cannot be simulated on this model at all (restoring-force
            # hysteresis below an input-level effect): it gains nothing, nothing crashes
            th, yw = th0, ctx.yhat
    if not np.all(np.isfinite(yw)):
        th, yw = th0, ctx.yhat
    fw = float(np.mean(fit_percent(ctx.y[ctx.val], yw[ctx.val])))
    return Refit(ext, th, yw, fw, time.perf_counter() - t0)


def _words(eff, ctx: Context, sig) -> tuple[str, dict[str, Any]]:
    """The explanation and evidence of ``eff``'s signature: an effect that emits an
    evidence code (``evidence(ctx, sig) -> (code, numbers)``) is worded by
    :mod:`rigd.diagnose.wording` for the record's domain; the others still word their own."""
    if not hasattr(eff, "evidence"):
        return eff.explain(ctx, sig)
    code, ev = eff.evidence(ctx, sig)
    text = W.explanation(eff.name, code, dict(ev, share=sig.score, fs=ctx.fs), ctx.domain)
    return text, dict(ev, code=code)


def _screen(ctx: Context, names: list[str], refit: bool, data_est, max_nfev,
            cannot: list[CannotReveal] | None,
            method: str = "oe") -> tuple[list[Finding], dict[str, Refit]]:
    """Signature test (and refit) of each effect in ``names`` on the model of ``ctx``.

    ``score`` is the share of *this* model's validation error energy the effect removes;
    effects the record cannot reveal go to ``cannot`` (when given) and are skipped.
    """
    findings, refits = [], {}
    err = _val_err(ctx, ctx.yhat)
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
            if getattr(eff, "costly_refit", False)
            else sig.score > 0.005 or sig.f_p < P_LEVEL)
        if refit and worth_refit:
            ref = _refit(eff, ctx, sig, data_est, max_nfev, method)
            refits[name] = ref
            gain = max(0.0, 1.0 - _val_err(ctx, ref.yhat) / err) if err > 0 else 0.0
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
            why_not = eff.implausible(ctx, np.asarray(ref.theta)[len(ctx.theta):])
            if why_not is not None:
                # it helps, but not as the physics its name says: unexplained, not named
                f.evidence["implausible"] = why_not
                f.significant = False
        else:
            f.evidence["refit"] = "not refitted: no signature in the residual"
        findings.append(f)
    findings.sort(key=lambda f: (not f.significant, -f.score, -f.signature_score))
    return findings, refits


def diagnose_data(data, submodel: str, structure=None, est: slice | None = None,
                  val: slice | None = None, effects: list[str] | None = None,
                  refit: bool = True, max_nfev: int | None = None,
                  theta0: np.ndarray | None = None,
                  max_steps: int = MAX_STEPS, offsets: dict[str, float] | None = None,
                  start: int = 0, other_hold: str | None = None,
                  yardstick=None, record_meta: dict | None = None, method: str = "oe",
                  base_theta: np.ndarray | None = None) -> SubDiagnosis:
    """Diagnose one sub-model on identification data by forward selection.

    Like a stepwise regression: fit the base model; test every effect on its residual
    (signature + refit); add the top significant one, refit, and test the remaining effects
    again on the residual of the extended model; repeat until nothing significant is left
    or ``max_steps`` effects were added. So an effect masked by a stronger one is found once
    the stronger one is in the model, and an effect that only mimicked part of the stronger
    one's signature is no longer significant once that one is in.

    Parameters
    ----------
    data : IdData
        Prefiltered data of the whole (analysed) record.
    submodel : str
        ``actuator``, ``bearing`` or ``generic``.
    structure : Structure, optional
        Base structure (default: ``structure_for(submodel, hold=DEFAULT_HOLD[submodel])``,
        what ``rigd identify`` fits).
    est, val : slice, optional
        Estimation and validation parts (default: first 2/3, last 1/3).
    effects : list of str, optional
        Effects to test (default: every registered effect concerning the sub-model).
    refit : bool
        Refit each revealable effect (``fit_percent_with``); off: signature only, no steps.
    theta0 : ndarray, optional
        Start values of the base fit.
    max_steps : int
        Most effects added.
    other_hold : {"zoh", "foh"}, optional
        For a hold chosen from the data by the linear base: after each added effect the
        model is refitted with this hold too and switched to it when it fits ≥
        ``MIN_FIT_GAIN`` points better (a note says so).
    method : {"oe", "pem"}
        Fit method of the base (unless ``base_theta`` is given) and of every refit.
    base_theta : ndarray, optional
        The base already fitted on ``est`` (rigd.ident.pipeline.fit_base): not refitted.
    offsets : dict, optional
        Prefilter offsets per channel (levels under ``unexplained`` in the record's units).
    start : int
        Index of ``data``'s first sample in the record (samples under ``unexplained``).
    yardstick : rigd.ident.yardstick.Yardstick, optional
        Black-box references on the same split: what is reachable (``unexplained``); its
        ``model_fit`` is set to the base model's fit.
    record_meta : dict, optional
        The record's metadata (its ``source``: a rigd recording is a rotor record), for
        the domain (:func:`rigd.diagnose.domain.decide`) that words the findings.

    Returns
    -------
    SubDiagnosis
        ``findings``: the added effects first, in the order added (``significant``; score =
        share of the base model's validation error energy their step removed;
        ``fit_percent_with`` = fit after their step), then the others as tested on the final
        model (not significant; score on the base model's scale; ``fit_percent_with`` = fit
        of the final model extended by them).
    """
    n = data.n
    if est is None or val is None:
        k = int(round(2 * n / 3))
        est, val = slice(0, k), slice(k, n)
    structure = structure or structure_for(submodel, data,
                                           hold=DEFAULT_HOLD.get(submodel, "zoh"))
    data_est = data.slice(est.start, est.stop)
    if base_theta is not None:
        theta = np.asarray(base_theta, float)
    else:
        theta = _fit(structure, data_est, theta0=theta0, max_nfev=max_nfev,
                     method=method).theta
    yhat = np.asarray(structure.simulate(theta, data), float)
    omega_hz = float(getattr(data, "meta", {}).get("omega_rpm", 0.0) or 0.0) / 60.0
    dom = D.decide(submodel, record_meta or {}, structure, theta)
    taus = D.time_constants(structure, theta)

    def context(st, th, yh):
        return Context(submodel, data, st, th, yh, est, val, omega_hz,
                       model_resonances(st, th), list(data.input_names),
                       list(data.output_names), dom.name, taus)

    ctx0 = context(structure, theta, yhat)
    fp_base = float(np.mean(fit_percent(ctx0.y[val], yhat[val])))
    err_base = _val_err(ctx0, yhat)
    steps = [Step(None, fp_base, structure, theta, yhat)]
    cannot: list[CannotReveal] = []
    names = effects or [nm for nm, e in REGISTRY.items()
                        if submodel in e.submodels and getattr(e, "screened", True)]
    notes: list[str] = [f"domain: {dom.name} ({dom.why})"]
    if not effects:  # effects this domain cannot carry are not offered (not named either)
        kept = [nm for nm in names if D.offered(REGISTRY[nm], dom)]
        if len(kept) < len(names):
            notes.append(f"effects of mechanical structures or rotating parts are not tested "
                         f"on a {dom.name} record")
        names = kept
    n_est = (est.stop or n) - (est.start or 0)
    if not effects:  # costly effects are screened by default on records they can afford
        for nm in list(names):
            cap = getattr(REGISTRY[nm], "max_screened_samples", None)
            if cap is not None and n_est > cap:
                names.remove(nm)
                notes.append(f"{nm} not screened: {n_est} estimation samples > {cap} (its "
                             f"fits cost minutes there); ask for it with --effects {nm}")
    for nm in list(names):  # an effect the base cannot carry is not offered, and says why
        why_not = REGISTRY[nm].not_offered(structure)
        if why_not is not None:
            names.remove(nm)
            notes.append(f"{nm} not offered: {why_not}")
    added: list[Finding] = []
    refits: dict[str, Refit] = {}
    # an effect the base model already carries (a pole slower than the record: an
    # integrator) is named from the base, not added (Effect.carried_by_base)
    carried = [f for f in (REGISTRY[nm].carried_by_base(ctx0) for nm in names) if f is not None]
    names = [nm for nm in names if nm not in {f.effect for f in carried}]
    ctx = ctx0
    findings, round_refits = _screen(ctx, names, refit, data_est, max_nfev, cannot, method)
    revealable = [f.effect for f in findings]
    while True:
        err_cur = _val_err(ctx, ctx.yhat)
        top = findings[0] if findings and findings[0].significant else None
        if top is None or not refit or len(added) >= max_steps:
            break
        ref = round_refits[top.effect]
        err_new = _val_err(ctx, ref.yhat)
        top.score = (err_cur - err_new) / err_base if err_base > 0 else 0.0
        if added:
            top.explanation = (f"with {', '.join(f.effect for f in added)} added: "
                               f"{top.explanation}")
            top.evidence["found_after"] = [f.effect for f in added]
        top.evidence["step"] = len(added) + 1
        added.append(top)
        step = Step(top.effect, ref.fit_percent, ref.structure, ref.theta, ref.yhat)
        alt = _try_hold(step, ctx0, other_hold, data_est, method) if other_hold else None
        if alt is not None:
            notes.append(f"inputs between samples: with {top.effect} in the model, "
                         f"{other_hold} fits {alt.fit_percent:.2f} % against "
                         f"{step.fit_percent:.2f} % (the hold was chosen by the linear base "
                         f"model): {other_hold} from this step on (rigd identify --hold "
                         f"{other_hold})")
            top.evidence["hold"] = other_hold
            top.fit_percent_with = alt.fit_percent
            top.score = (err_cur - _val_err(ctx, alt.yhat)) / err_base if err_base > 0 else 0.0
            ref = Refit(alt.structure, alt.theta, alt.yhat, alt.fit_percent, ref.seconds)
            step, other_hold = alt, None
        refits[top.effect] = ref
        steps.append(step)
        ctx = context(step.structure, step.theta, step.yhat)
        rest = [nm for nm in revealable if nm not in {f.effect for f in added}]
        if not rest:
            findings = []
            break
        findings, round_refits = _screen(ctx, rest, refit, data_est, max_nfev, None, method)
    # what remains, tested on the final model: not significant by the stepwise decision
    # (when the step cap was reached, a still significant one keeps its flag)
    scale = (err_cur / err_base) if err_base > 0 else 1.0
    for f in findings:
        f.score *= scale
        if len(added) < max_steps:
            f.significant = False
        if f.effect in round_refits:
            refits.setdefault(f.effect, round_refits[f.effect])
    findings.sort(key=lambda f: (not f.significant, -f.score, -f.signature_score))
    # a partial "cannot tell" (slow creep) is void once the effect was found
    cannot = [c for c in cannot if not (c.partial and c.effect in {f.effect for f in added})]
    if yardstick is not None:
        yardstick.model_fit = fp_base
    sd = SubDiagnosis(submodel, fp_base, carried + added + findings, cannot, [], ctx0, {},
                      refits, (0, data.n), steps, notes=notes, yardstick=yardstick, domain=dom)
    _tests_and_unexplained(sd, offsets, start)
    return sd


def _corr_tests(ctx: Context, r: np.ndarray) -> dict[str, Any]:
    """Whiteness of each output's residual ``r`` (validation part) and its cross-correlation
    with each input (99 % bounds)."""
    v = ctx.val
    tests: dict[str, Any] = {"whiteness": {}, "cross_correlation": {}}
    for i in range(ctx.ny):
        w = R.whiteness(r[:, i])
        tests["whiteness"][ctx.label(i)] = {"passed": w.passed, "outside": w.outside}
        for j in range(ctx.nu):
            c = R.cross_correlation(r[:, i], ctx.u[v, j])
            tests["cross_correlation"][f"{ctx.label(i)}~{ctx.label(j, 'in')}"] = {
                "passed": c.passed, "outside": c.outside}
    return tests


def _tests_and_unexplained(sd: SubDiagnosis, offsets: dict[str, float] | None = None,
                           start: int = 0) -> None:
    """Whiteness / cross-correlation tests of the base model (``tests``) and of the final
    model (``tests["final_model"]``, with its residual level against the noise estimate),
    and the structure the final model leaves unexplained (:mod:`rigd.diagnose.unexplained`;
    ``offsets`` per channel and the record index ``start`` of the data put its levels and
    samples in the record's terms)."""
    ctx = sd.ctx
    v = ctx.val
    tests = _corr_tests(ctx, ctx.residual[v])
    sd.tests = tests
    # the best model found: the last forward-selection step
    yb = sd.final.yhat
    rb = (ctx.y - yb)[v]
    sig = {f.effect for f in sd.findings if f.significant}
    final_tests = _corr_tests(ctx, rb)
    reach = (sd.yardstick.reachable(sd.final.fit_percent) if sd.yardstick is not None
             else None)
    w = 1.0 / np.maximum(np.std(ctx.y[v], axis=0), 1e-300)
    lev = U.level(rb * w, ctx.y[v] * w, None if reach is None else reach["residual"] * w)
    tests["final_model"] = dict(final_tests, level={
        "rms_over_noise": round(min(lev["ratio"], 1e6), 3),
        "structured_share": round(lev["structured_share"], 4),
        "worth_fit_points": round(U.worth(lev, ctx.y[v], rb), 3),
        **({"reachable_fit_points": round(reach["fit"] - reach["model_fit"], 3)}
           if reach is not None else {})})
    skip = ([k * ctx.omega_hz for k in (1, 2)]
            if ctx.omega_hz > 0 and "runout" in sig else None)
    unexplained = U.report(rb, ctx.y[v], yb[v], ctx.u[v], ctx.fs, final_tests,
                           model_resonances(sd.final.structure, sd.final.theta),
                           ctx.output_names or [ctx.label(i) for i in range(ctx.ny)],
                           ctx.input_names or [ctx.label(j, "in") for j in range(ctx.nu)],
                           skip_hz=skip, offsets=offsets, start=start + (v.start or 0),
                           reference=reach, domain=ctx.domain)
    err_final = max(100.0 - sd.final.fit_percent, 1e-12)
    for f in sd.findings:
        why_not = f.evidence.get("implausible")
        if why_not and f.fit_percent_with - sd.final.fit_percent >= MIN_FIT_GAIN:
            # share of the final model's error energy the implausible refit removed
            ratio = (100.0 - f.fit_percent_with) / err_final
            unexplained.append({
                "where": {"effect_tried": f.effect},
                "fit_gain_percent": round(f.fit_percent_with - sd.final.fit_percent, 3),
                "share": round(min(max(1.0 - ratio ** 2, 0.0), 1.0), 4),
                "text": f"{why_not} ({f.effect} refit: fit {f.fit_percent_with:.2f} %)"})
    sd.unexplained = unexplained



def _try_hold(step: Step, ctx0: Context, hold: str, data_est,
              method: str = "oe") -> Step | None:
    """``step``'s model refitted with the input hold ``hold``, if that fits the validation
    part better by ≥ ``MIN_FIT_GAIN`` points, else None.

    For records whose hold was chosen from the data by the *linear* base model: an
    unmodelled nonlinearity can favour a half-sample lag (the Bouc–Wen benchmark's smooth
    multisine: zoh by 1.7 points for the linear model, foh by ≈ 8 once the hysteresis is
    in), so once an effect is in the model the question is asked again.
    """
    import copy

    st = copy.deepcopy(step.structure)
    obj, seen = st, 0
    while obj is not None and seen < 20:  # the hold lives on the base and its wrappers
        if isinstance(vars(obj).get("hold"), str):
            obj.hold = hold
        obj, seen = vars(obj).get("base"), seen + 1
    eff = REGISTRY.get(step.added or "")
    fixed = list(getattr(eff, "refit_fixed", lambda e: [])(st)) or None
    try:
        th = _fit(st, data_est, theta0=step.theta, fixed=fixed, method=method).theta
        yh = np.asarray(st.simulate(th, ctx0.data), float)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return None
    if not np.all(np.isfinite(yh)):
        return None
    fp = float(np.mean(fit_percent(ctx0.y[ctx0.val], yh[ctx0.val])))
    return Step(step.added, fp, st, th, yh) if fp >= step.fit_percent + MIN_FIT_GAIN else None
