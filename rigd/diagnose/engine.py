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
   and its refit lowers the validation error energy by at least ``MIN_REFIT_GAIN``; like a
   stepwise regression, the top significant one is added, the model refitted, and the
   remaining effects tested again on the residual of the extended model, until nothing
   significant is left or ``max_steps`` effects were added (an effect masked by a stronger
   one is found once that one is in; one that only mimicked part of its signature is no
   longer significant);
5. when the residual of the best model is still structured (whiteness or residual–input
   correlation fails, or it is above the noise estimate), it is reported as *unexplained*
   with where it lives (frequency bands, amplitude, time, direction of input motion), its
   share of the error energy and what it suggests (:mod:`rigd.diagnose.unexplained`).

This module is the per-data stepwise engine (:func:`diagnose_data`); whole records (sub-models,
window, split, input hold) are diagnosed by :func:`rigd.diagnose.diagnosis.diagnose_record`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.diagnose import domain as D
from rigd.diagnose import residual as R
from rigd.diagnose import selection as S
from rigd.diagnose import unexplained as U
from rigd.diagnose.selection import Refit, Step
from rigd.effects.context import CannotReveal, Context, Finding
from rigd.ident.figures import fit_percent
from rigd.ident.greybox.submodels import DEFAULT_HOLD, structure_for
from rigd.ident.pipeline import MAX_REFIT_FREE, held_base
from rigd.ident.thresholds import MIN_FIT_GAIN

#: most effects added by the forward selection
MAX_STEPS = 3


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
    #: the base fit itself (rigd.ident.pipeline.BaseFit: data, window, split), for
    #: rigd.diagnose.save; not in the JSON
    base_fit: Any = field(default=None, repr=False)
    #: with a given model (rigd.diagnose.given): it against its structure refitted here
    given: dict[str, Any] | None = None

    @property
    def final(self) -> Step:
        """The model after the last forward-selection step."""
        return self.steps[-1]


def model_resonances(structure, theta) -> list[float]:
    """Resonance frequencies (Hz) of the base model's linear part (rigd.ident.readouts)."""
    from rigd.ident.model import linear_part_of
    from rigd.ident.readouts import resonances_hz

    lp = linear_part_of(structure, theta)
    if lp is None or not np.all(np.isfinite(lp.A)):
        return []
    return sorted({round(f, 3) for f in resonances_hz(lp)})


def _remaining(sel, added: list[Finding], findings: list[Finding],
               cannot: list[CannotReveal], scale: float, max_steps: int
               ) -> tuple[list[Finding], list[CannotReveal]]:
    """The effects not added, as tested on the final model: not significant by the stepwise
    decision (when the step cap was reached, a still significant one keeps its flag), score
    on the base model's scale (``scale`` = final / base error energy); their refits kept in
    ``sel.refits``. A partial "cannot tell" (slow creep) is void once the effect was found."""
    for f in findings:
        f.score *= scale
        if len(added) < max_steps:
            f.significant = False
        if f.effect in sel.round_refits:
            sel.refits.setdefault(f.effect, sel.round_refits[f.effect])
    findings.sort(key=lambda f: (not f.significant, -f.score, -f.signature_score))
    names = {f.effect for f in added}
    return findings, [c for c in cannot if not (c.partial and c.effect in names)]


def diagnose_data(data, submodel: str, structure=None, est: slice | None = None,
                  val: slice | None = None, effects: list[str] | None = None,
                  refit: bool = True, max_nfev: int | None = None, theta0=None,
                  max_steps: int = MAX_STEPS, offsets: dict[str, float] | None = None,
                  start: int = 0, other_hold: str | None = None, yardstick=None,
                  record_meta: dict | None = None, method: str = "oe", base_theta=None,
                  carried_worth: dict[str, float] | None = None, memo=None) -> SubDiagnosis:
    """Diagnose one sub-model on identification data by forward selection (module
    docstring: a stepwise regression over the catalogue).

    Parameters
    ----------
    data : IdData
        Prefiltered data of the whole (analysed) record.
    submodel : str
        ``actuator``, ``bearing`` or ``generic``.
    structure : Model, optional
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
    carried_worth : dict, optional
        Per effect the base carries, the held-out fit points it loses without it (a delay:
        rigd.ident.lti.delay_worth); below ``MIN_FIT_GAIN`` the effect is not significant
        (rigd.diagnose.selection.carried).
    memo : rigd.diagnose.memo.RefitMemo, optional
        Refits done by an earlier run from the same models (rigd.diagnose.diagnosis runs
        the selection again from the same base): handed back, not fitted again.
    offsets, start : dict (optional), int
        Prefilter offsets per channel and the index of ``data``'s first sample in the
        record (levels and samples under ``unexplained`` in the record's terms).
    yardstick : rigd.ident.yardstick.Yardstick, optional
        Black-box references on the same split: what is reachable (``unexplained``); its
        ``model_fit`` is set to the base model's fit.
    record_meta : dict, optional
        The record's metadata (its ``source``: a rigd recording is a rotor record), for
        the domain (:func:`rigd.diagnose.domain.decide`) that words the findings.

    Returns
    -------
    SubDiagnosis
        ``findings``: the added effects in the order added (``significant``; score = share
        of the base's validation error energy their step removed; ``fit_percent_with`` =
        fit after it), then the others as tested on the final model (not significant; score
        on the base's scale; ``fit_percent_with`` = the final model extended by them).
    """
    n = data.n
    if est is None or val is None:
        k = int(round(2 * n / 3))
        est, val = slice(0, k), slice(k, n)
    structure = structure or structure_for(submodel, data,
                                           hold=DEFAULT_HOLD.get(submodel, "zoh"))
    data_est = data.slice(est.start, est.stop)
    if base_theta is None:
        base_theta = S.fit_model(structure, data_est, theta0=theta0, max_nfev=max_nfev,
                                 method=method).theta
    ctx0, context, dom = base_context(data, submodel, structure, base_theta, est, val,
                                       record_meta)
    notes: list[str] = [f"domain: {dom.name} ({dom.why})"]
    names = S.offered(effects, submodel, dom, structure, est, n, notes, data)
    held = held_base(structure, method)
    if held and refit:
        notes.append(f"the base has {len(held)} free parameters besides its output offsets "
                     f"(more than {MAX_REFIT_FREE}): each effect is refitted with the base "
                     "held, so its gain in fit is a lower bound (rigd identify --add refits "
                     "the same way)")
    sel = S.Selection(ctx0, context, refit, data_est, max_nfev, method, max_steps,
                      other_hold, [], notes, memo)
    sd = _stepwise(sel, ctx0, dom, names, carried_worth)
    if yardstick is not None:
        yardstick.model_fit = sd.fit_percent
    sd.yardstick = yardstick
    _tests_and_unexplained(sd, offsets, start)
    return sd


def _stepwise(sel, ctx0: Context, dom, names: list[str],
              carried_worth: dict[str, float] | None) -> SubDiagnosis:
    """The forward selection ``sel`` (rigd.diagnose.selection.Selection, its steps still
    empty) from the base model of ``ctx0`` over the effects ``names``: what the base already
    carries (a pole slower than the record: an integrator; Effect.carried_by_base) is named
    from it, not added; the rest is selected stepwise (module docstring)."""
    yhat, val = ctx0.yhat, ctx0.val
    fp_base = float(np.mean(fit_percent(ctx0.y[val], yhat[val])))
    err_base = S.val_err(ctx0, yhat)
    sel.steps.append(S.Step(None, fp_base, ctx0.structure, ctx0.theta, yhat))
    carried = S.carried(ctx0, names, dom, carried_worth)
    names = [nm for nm in names if nm not in {f.effect for f in carried}]
    cannot: list[CannotReveal] = []
    added, findings, err_cur = sel.run(names, cannot)
    findings, cannot = _remaining(sel, added, findings, cannot, err_cur / err_base
                                  if err_base > 0 else 1.0, sel.max_steps)
    return SubDiagnosis(ctx0.submodel, fp_base, carried + added + findings, cannot, [], ctx0,
                        {}, sel.refits, (0, ctx0.data.n), sel.steps, notes=sel.notes,
                        domain=dom)


def base_context(data, submodel: str, structure, theta, est: slice, val: slice,
                  record_meta: dict | None):
    """(context of the base model, the factory ``context(structure, theta, yhat)`` of the
    later steps' contexts, the record's domain): the base at ``theta`` simulated on the whole
    record, its domain and time constants (rigd.diagnose.domain) shared by every step."""
    theta = np.asarray(theta, float)
    yhat = np.asarray(structure.simulate(theta, data), float)
    omega_hz = float(getattr(data, "meta", {}).get("omega_rpm", 0.0) or 0.0) / 60.0
    dom = D.decide(submodel, record_meta or {}, structure, theta)
    taus = D.time_constants(structure, theta)

    def context(st, th, yh):
        return Context(submodel, data, st, th, yh, est, val, omega_hz,
                       model_resonances(st, th), list(data.input_names),
                       list(data.output_names), dom.name, taus)

    return context(structure, theta, yhat), context, dom


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
