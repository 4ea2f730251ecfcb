"""Diagnosis of a whole record: pick its sub-models, window and split, diagnose each.

:func:`diagnose_record` resolves the prefilters, input hold and estimation/validation split
exactly as ``rigd identify --method oe`` does and runs the per-sub-model engine
(:func:`rigd.diagnose.engine.diagnose_data`) on each sub-model; :class:`Diagnosis` collects the
parts and writes the JSON report; :func:`submodels_of` tells which sub-models a record supports.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.diagnose import selection as S
from rigd.diagnose.engine import MAX_STEPS, SubDiagnosis, diagnose_data
from rigd.ident.pipeline import MAX_SAMPLES
from rigd.ident.yardstick import measure


@dataclass
class Diagnosis:
    """Diagnosis of a record: one :class:`SubDiagnosis` per sub-model examined."""

    parts: list[SubDiagnosis]
    source: str = ""
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        multi = len(self.parts) > 1
        if multi:
            fp: Any = {p.submodel: round(p.fit_percent, 3) for p in self.parts}
        else:
            fp = round(self.parts[0].fit_percent, 3)
        findings = [f for p in self.parts for f in p.findings]
        # significant (added) ones first in each part's order of addition, then by score
        # (a flagged refit — worse than its model, below 0 % or diverged — last, unranked)
        findings.sort(key=lambda f: (not f.significant, "refit_flag" in f.evidence,
                                     0.0 if f.significant else -f.score,
                                     f.evidence.get("step", 0) if f.significant else 0))
        if multi:  # added effects of several parts: the larger step first
            findings.sort(key=lambda f: (not f.significant, "refit_flag" in f.evidence,
                                         -f.score if f.significant else 0))
        return {
            "fit_percent": fp,
            "findings": [f.to_json(True) for f in findings],
            "cannot_reveal": [c.to_json(True) for p in self.parts for c in p.cannot_reveal],
            "unexplained": [dict(u, submodel=p.submodel) for p in self.parts
                            for u in p.unexplained],
            "steps": ({p.submodel: [s.to_json() for s in p.steps] for p in self.parts}
                      if multi else [s.to_json() for s in self.parts[0].steps]),
            "tests": {p.submodel: p.tests for p in self.parts},
            "analysed_samples": {p.submodel: list(p.window) for p in self.parts},
            "order": {p.submodel: p.order for p in self.parts if p.order is not None},
            "domain": {p.submodel: p.domain.to_json() for p in self.parts
                       if p.domain is not None},
            "yardstick": {p.submodel: p.yardstick.to_json() for p in self.parts
                          if p.yardstick is not None},
            "base": {p.submodel: p.base for p in self.parts if p.base is not None},
            **({"given_model": {p.submodel: p.given for p in self.parts if p.given}}
               if any(p.given for p in self.parts) else {}),
            "notes": list(self.notes),
        }


def submodels_of(record) -> list[str]:
    """Sub-models a record supports: generic, or actuator and/or bearing."""
    if record.is_generic:
        return ["generic"]
    out = []
    if record.has("r_x", "r_y", "u_x", "u_y"):
        out.append("actuator")
    if record.has("u_x", "u_y", "e_x", "e_y"):
        out.append("bearing")
    return out


def diagnose_record(record, runout=None, submodels: list[str] | None = None,
                    est: slice | None = None, val: slice | None = None,
                    effects: list[str] | None = None, refit: bool = True,
                    max_samples: int | None = MAX_SAMPLES, options=None,
                    hold: str = "auto", split: float | None = None,
                    max_steps: int = MAX_STEPS, order: str | int = "auto",
                    method: str = "oe", init=None, yardstick: bool = True,
                    model=None, model_path: str = "--model") -> Diagnosis:
    """Diagnose a :class:`rigd.data.Record` (prefilters of §4.4, then each sub-model).

    The base model of each sub-model is :func:`rigd.ident.pipeline.fit_base`'s, the one
    ``rigd identify`` keeps with the same settings (``method``, ``init``, window, split,
    hold, order, prefilters): for the same settings the two are the same numbers. The
    forward selection refits with the same method (:func:`rigd.ident.pipeline.refit_with`).
    Diagnose's default method is output error (``oe``: the residual of a simulation is what
    is analysed), so ``rigd identify --method oe`` gives diagnose's default base model.

    Records longer than ``max_samples`` are analysed on their central ``max_samples``
    samples (:func:`rigd.ident.pipeline.analysis_window`, as ``rigd identify``; a note says
    which).

    ``order`` (generic records): ``"auto"`` — the number of modes is chosen from the data
    (:func:`rigd.ident.greybox.order.choose_order`), so the effects are sought on the best linear
    model of the class; or the number of modes.

    ``yardstick``: fit a plain ARX and a subspace model on the same split
    (:mod:`rigd.ident.yardstick`): reported beside the base model (``yardstick`` in the
    JSON, a warning when the base is worse) and the measure of what is reachable for the
    structure left unexplained (:mod:`rigd.diagnose.unexplained`).

    ``model`` (a :class:`rigd.ident.modelfile.ModelFile`, read from ``model_path``): the base
    is that model, not fitted on this record (:mod:`rigd.diagnose.given`): what it misses
    here, and what its own structure refitted here changes, in words (``given_model``).
    """
    from rigd.errors import InputError
    from rigd.ident.pipeline import FitSettings

    subs = submodels or submodels_of(record)
    if not subs:
        raise InputError("record has neither inputs/outputs metadata nor the rotor columns "
                         "r_x, r_y, u_x, u_y (actuator) or u_x, u_y, e_x, e_y (bearing)",
                         record.source)
    settings = FitSettings(method=method, split=split, est=est, val=val, hold=hold,
                           order=order, init=init, options=options, runout=runout,
                           max_samples=max_samples)
    settings.check()
    # effects asked by name that act on a mechanical state (a stiffness, a restoring force)
    # keep the mechanical base, as rigd identify --add does (FitSettings.mechanical)
    from rigd.effects import REGISTRY

    settings.mechanical = any(
        "mechanical" in REGISTRY[nm].requires
        for nm in (effects or []) if nm in REGISTRY)
    notes: list[str] = []
    if model is not None:
        subs = [s for s in subs if s in model.submodels] or subs
    parts = [_diagnose_part(record, sub, settings, notes, effects=effects, refit=refit,
                            max_steps=max_steps, yardstick=yardstick,
                            given=(model, model_path) if model is not None else None)
             for sub in subs]
    return Diagnosis(parts, record.source, notes)


def _diagnose_part(record, sub: str, settings, notes: list[str], *, effects, refit: bool,
                   max_steps: int, yardstick: bool, given=None) -> SubDiagnosis:
    """Diagnose one sub-model of ``record``: its base model (:func:`rigd.ident.pipeline.
    fit_base` with ``settings``), the yardstick, the forward selection
    (:func:`rigd.diagnose.engine.diagnose_data`) and the sanity warnings of the base and the
    final model; the notes of the part are appended to ``notes``."""
    from rigd.ident.pipeline import fit_base
    from rigd.ident.sanity import model_warnings

    drift = None
    if given is None:
        bf = fit_base(record, sub, settings)
    else:   # the base is a given model, not fitted here (rigd.diagnose.given)
        from rigd.diagnose.given import given_base

        bf, drift = given_base(record, sub, settings, *given)
    for nt in bf.notes:
        if nt not in notes:
            notes.append(nt)
    offsets = (bf.prefilter.get("offsets") or {}).get("values", {})
    notes.append(f"{sub}: inputs between samples: {bf.hold.describe()}")
    notes.append(f"{sub}: base model: " + (_describe_base(bf) if drift is None else
                                           f"the given model {given[1]}, not refitted"))
    if bf.order is not None:
        notes += [f"{sub}: {n}" for n in _order_notes(bf)]
    # the yardstick: what a plain linear model reaches on the same split (also the
    # measure of what is reachable for the unexplained structure)
    ys = (measure(bf.data.u, bf.data.y, bf.est, bf.val, float("nan"), bf.data.fs)
          if yardstick else None)
    from rigd.diagnose.memo import RefitMemo

    memo = RefitMemo()   # a refit asked again from the same model is not fitted again

    def run(structure, theta, ys, worth=None, only=None):
        return diagnose_data(bf.data, sub, structure=structure, est=bf.est, val=bf.val,
                             effects=only or effects, refit=refit, max_steps=max_steps,
                             base_theta=theta, method=bf.settings.method,
                             carried_worth=worth,
                             offsets=offsets, start=bf.window[0], yardstick=ys,
                             record_meta=record.meta, memo=memo,
                             # a hold chosen by the linear base is asked again with the
                             # effects
                             other_hold=S.other_hold(bf))

    sd = run(bf.structure, bf.theta, ys, _carried_worth(bf))
    on = None
    mech = (mechanical_alternative(bf, record.meta)
            if not effects and refit and drift is None else None)
    if mech is not None:
        import copy

        alt = run(mech.structure, mech.theta, copy.copy(ys))
        sd, on, why = better_on_mechanical(sd, alt)
        notes.append(f"{sub}: state-level effects screened on the mechanical n-DOF base as "
                     f"well (the general LTI base has no input delay or integrator: "
                     f"docs/diagnose.md): {why}")
    rechosen = None
    if not effects and refit and on is None and drift is None:
        sd, rechosen = _rebased(bf, sd, ys, run, sub, notes)
    if bf.order is not None:
        sd.order = bf.order.to_json()
        if on is not None:
            sd.order["diagnosed_on"] = on
    sd.base = bf.to_json()
    sd.base_fit = bf
    sd.given = drift
    if on is not None:
        sd.base["diagnosed_on"] = on
    if rechosen is not None:
        sd.base["rechosen_with_curve"] = rechosen
    notes += [f"{sub}: {n}" for n in sd.notes]
    for st, what in ((sd.steps[0], "base model"), (sd.final, "final model")):
        if what == "final model" and len(sd.steps) == 1:
            break
        notes += [f"{sub}: {what}: WARNING: {w}" for w in model_warnings(st.structure,
                                                                        st.theta)]
    if ys is not None and ys.warning():
        notes.append(f"{sub}: base model: WARNING: {ys.warning()}")
    sd.window = bf.window
    return sd


def _rebased(bf, sd: SubDiagnosis, ys, run, sub: str, notes: list[str]):
    """(``sd`` or the diagnosis from another linear candidate, what was chosen or None):
    when a static curve was added, each other candidate is diagnosed with the effects
    ``sd`` added (a forward selection over them only: one refit or two per candidate, not
    the catalogue's screening), the best kept when its final model fits better
    (rigd.diagnose.rebase.best_final); the kept one is then diagnosed over the whole
    catalogue and must still beat ``sd`` by the same margin."""
    import copy

    from rigd.diagnose import rebase

    alts = rebase.alternatives(bf, sd)
    if not alts:
        return sd, None
    added = [s.added for s in sd.steps[1:] if s.added]
    worth = {id(c): _carried_worth(bf, c.structure, c.theta) for c in alts}
    runs = [(c, run(c.structure, c.theta, copy.copy(ys), worth[id(c)], only=added))
            for c in alts]
    kept, why = rebase.best_final(sd, runs)
    if kept is not sd:   # the whole catalogue on the candidate kept
        cand = next(c for c, d in runs if d is kept)
        kept, why = rebase.best_final(sd, [(cand, run(cand.structure, cand.theta,
                                                      copy.copy(ys), worth[id(cand)]))])
    notes.append(f"{sub}: {why}")
    if kept is sd:
        return sd, None
    return kept, {"family": cand.family, "states": int(cand.states),
                  "delays": [int(d) for d in cand.structure.delays],
                  "fit_percent": round(float(kept.fit_percent), 3),
                  "identify_base_fit_percent": round(float(sd.fit_percent), 3),
                  "identify_base_final_fit_percent": round(float(sd.final.fit_percent), 3)}


def _carried_worth(bf, structure=None, theta=None) -> dict[str, float] | None:
    """What the input delays of a generic record's base (or of ``structure`` at ``theta``,
    another base of it) are worth on held-out data
    (:func:`rigd.ident.lti.delay_worth.delay_worth`), for the ``delay`` it carries."""
    if bf.order is None:
        return None
    from rigd.ident.lti.delay_worth import delay_worth

    pts = delay_worth(structure or bf.structure, bf.theta if theta is None else theta,
                      bf.data, bf.est, bf.val)
    return None if pts is None else {"delay": pts}


def mechanical_alternative(bf, meta: dict | None = None):
    """The mechanical n-DOF candidate of a generic record's base choice on which the
    state-level effects (which only a mechanical base carries) are screened as well, or None.

    The rule (docs/diagnose.md, "Which base the state-level effects are screened on"):
    the order was chosen from the data (``auto``), the chosen base is not the mechanical
    model, the record is of the mechanical domain (a lightly damped pole pair,
    :func:`rigd.diagnose.domain.decide`), and the chosen base is what the mechanical model
    carries plus poles of its own: no input delay and no integrator, and any number of
    modes and real poles. Both are what the linear shadow of a state-level nonlinearity
    looks like — a hysteretic restoring force lags the motion (a real pole next to the
    mode), and its distortion at three times the resonance takes a mode there (the
    Bouc–Wen benchmark's variant 1: 1 pair + 1 real pole + a "mode" at 36.2 Hz) — so the
    base choice alone cannot tell them from real dynamics: the diagnosis must, with the
    effect in.
    """
    from rigd.diagnose import domain as D

    ch = bf.order
    if ch is None or getattr(ch, "family", "mechanical") == "mechanical" or \
            getattr(ch, "asked", "auto") != "auto":
        return None
    mech = [c for c in getattr(ch, "candidates", []) if c.family == "mechanical"
            and np.isfinite(c.fit_val)]
    if not mech:
        return None
    if (any(int(d) != 0 for d in ch.delays) or bf.structure.n_integrators
            or ch.modes < 1):
        return None
    if D.decide(bf.submodel, meta or {}, bf.structure, bf.theta).name != "mechanical":
        return None
    return mech[0]


def better_on_mechanical(sd: SubDiagnosis, alt: SubDiagnosis):
    """(diagnosis reported, ``diagnosed_on`` entry or None, why): the diagnosis ``alt`` on
    the mechanical base replaces ``sd`` (on identify's base) when it added an effect that
    ``sd``'s base cannot carry and its final held-out fit is at least ``MIN_FIT_GAIN``
    points higher."""
    from rigd.effects import REGISTRY
    from rigd.ident.thresholds import MIN_FIT_GAIN

    base0 = sd.steps[0].structure
    only = [s.added for s in alt.steps[1:]
            if s.added in REGISTRY and REGISTRY[s.added].not_offered(base0) is not None]
    a, b = sd.final.fit_percent, alt.final.fit_percent
    path = " -> ".join(f"{s.added or 'base'} {s.fit_percent:.2f} %" for s in alt.steps)
    if only and b >= a + MIN_FIT_GAIN:
        on = {"family": "mechanical", "fit_percent": round(float(alt.fit_percent), 3),
              "identify_base_fit_percent": round(float(sd.fit_percent), 3),
              "identify_base_final_fit_percent": round(float(a), 3),
              "effects_not_on_identify_base": only}
        return alt, on, (f"there {path}, on the general LTI base {a:.2f} % at best: the "
                         f"diagnosis below is the mechanical base's (rigd identify --add "
                         f"{' '.join(only)} fits it on that base)")
    return sd, None, (f"there {path}; kept the general LTI base's diagnosis ({a:.2f} %)")


def _describe_base(bf) -> str:
    """One line: method, samples, split and start values of the base fit."""
    b = bf.to_json()
    a, z = b["window"]
    est = [a + (bf.est.start or 0), a + bf.est.stop]
    val = [a + (bf.val.start or 0), a + bf.val.stop]
    return (f"{b['method_used']} fit on samples {est[0]}:{est[1]}, validated on "
            f"{val[0]}:{val[1]} of {b['record_samples']}; start values: {b['start']} "
            f"(rigd identify with the same options fits the same model"
            f"{'' if b['method'] == 'pem' else ': --method oe'})")


def _order_notes(bf) -> list[str]:
    """The order chosen and, when the base has more modes than one per output, the modes a
    mechanical model of one DOF per output misses (with its held-out fit)."""
    from rigd.ident.readouts import resonances_hz
    from rigd.ident.thresholds import MODE_SEPARATION

    chosen, structure = bf.order, bf.structure
    out = [f"base model order: {chosen.describe()}"]
    if structure.n_parallel_modes:   # the mechanical base + parallel modes
        missed = ", ".join(f"{f:.4g} Hz" for f, _, _ in structure.modes_of(bf.theta))
        out.append(f"one mode per output misses mode(s) at {missed}: the base model has "
                   f"{chosen.modes} modes (fit {chosen.fits[structure.n]:.2f} % with "
                   f"{structure.n})")
        return out
    ny = len(bf.data.output_names)
    if chosen.modes <= ny:
        return out
    mech = [c for c in getattr(chosen, "candidates", []) if c.family == "mechanical"]
    have = []
    if mech:
        have = resonances_hz(mech[0].structure.linear_part(mech[0].theta))
    got = resonances_hz(structure.linear_part(bf.theta))
    missed = [f for f in got if all(abs(f - h) > MODE_SEPARATION * h for h in have)]
    if not missed:
        return out
    with_one = (f" (fit {mech[0].fit_val:.2f} % with {ny})" if mech else "")
    out.append(f"one mode per output misses mode(s) at "
               f"{', '.join(f'{f:.4g} Hz' for f in missed)}: the base model has "
               f"{chosen.modes} modes{with_one}")
    return out
