"""Diagnosis of a whole record: pick its sub-models, window and split, diagnose each.

:func:`diagnose_record` resolves the prefilters, input hold and estimation/validation split
exactly as ``rigd identify --method oe`` does and runs the per-sub-model engine
(:func:`rigd.diagnose.engine.diagnose_data`) on each sub-model; :class:`Diagnosis` collects the
parts and writes the JSON report; :func:`submodels_of` tells which sub-models a record supports.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rigd.diagnose.engine import MAX_STEPS, SubDiagnosis, diagnose_data
from rigd.ident.hold import choose_hold
from rigd.ident.mechanical import structure_for
from rigd.ident.yardstick import measure

#: longest stretch analysed (samples); longer records are analysed on a window
MAX_SAMPLES = 40_000


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
        findings.sort(key=lambda f: (not f.significant, 0.0 if f.significant else -f.score,
                                     f.evidence.get("step", 0) if f.significant else 0))
        if multi:  # added effects of several parts: the larger step first
            findings.sort(key=lambda f: (not f.significant, -f.score if f.significant else 0))
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
                    max_samples: int = MAX_SAMPLES, options=None,
                    hold: str = "auto", split: float | None = None,
                    max_steps: int = MAX_STEPS, order: str | int = "auto",
                    yardstick: bool = True) -> Diagnosis:
    """Diagnose a :class:`rigd.data.Record` (prefilters of §4.4, then each sub-model).

    The base model of each sub-model is what ``rigd identify --method oe`` fits on the same
    samples: the same prefilters (:func:`rigd.ident.workflow.prepare`, default
    :class:`~rigd.ident.prefilter.PrefilterOptions`), the same structure and input hold
    (``hold="auto"``: as :func:`rigd.ident.hold.choose_hold` resolves it — declared by the
    record, known for rigd recordings, else chosen from the data; or ``zoh``/``foh`` for every
    sub-model) and, without
    ``est``/``val``, the same split (first ``split`` of the samples estimate, default 2/3).

    Records longer than ``max_samples`` are analysed on their central ``max_samples``
    samples (a note says which; ``rigd identify --range A:B`` fits the same window).

    ``order`` (generic records): ``"auto"`` — the number of modes is chosen from the data
    (:func:`rigd.ident.order.choose_order`: subspace estimate of what the residual still
    carries, output-error refinement, kept while it adds ≥ 0.5 validation points), so the
    effects are sought on the best linear model of the class; or the number of modes.
    A higher order than one mode per output is reported (note and ``order`` in the JSON).

    ``yardstick``: fit a plain ARX and a subspace model on the same split
    (:mod:`rigd.ident.yardstick`): reported beside the base model (``yardstick`` in the
    JSON, a warning when the base is worse) and the measure of what is reachable for the
    structure left unexplained (:mod:`rigd.diagnose.unexplained`).
    """
    from rigd.errors import InputError
    from rigd.ident.workflow import DEFAULT_SPLIT, prepare

    subs = submodels or submodels_of(record)
    if not subs:
        raise InputError("record has neither inputs/outputs metadata nor the rotor columns "
                         "r_x, r_y, u_x, u_y (actuator) or u_x, u_y, e_x, e_y (bearing)",
                         record.source)
    if hold not in ("auto", "zoh", "foh"):
        raise InputError(f"hold must be auto, zoh or foh (got {hold!r})", "--hold")
    notes = []
    n = record.n
    window = (0, n)
    if est is None and val is None and n > max_samples:
        a = (n - max_samples) // 2
        window = (a, a + max_samples)
        notes.append(f"long record: analysed samples {window[0]}..{window[1]} of {n} "
                     f"(rigd identify --range {window[0]}:{window[1]} fits the same window)")
        record = record.slice(*window)
    if est is None and val is None:
        frac = DEFAULT_SPLIT if split is None else float(split)
        if not 0.2 <= frac <= 0.95:
            raise InputError(f"split must be within 0.2..0.95 (got {frac})", "--split")
        k = int(round(record.n * frac))
        est, val = slice(0, k), slice(k, record.n)
    parts = []
    for sub in subs:
        data, rep = prepare(record, sub, options, runout)
        offsets = (rep.get("offsets") or {}).get("values", {})
        choice = choose_hold(sub, data.slice(est.start, est.stop), record.meta, hold,
                             where=record.source)
        notes.append(f"{sub}: inputs between samples: {choice.describe()}")
        structure = structure_for(sub, data, hold=choice.hold)
        theta0, chosen = None, None
        if sub == "generic":
            from rigd.ident.order import ModalStructure, choose_order

            try:
                chosen = choose_order(structure, data, est, val, order)
            except ValueError as exc:
                raise InputError(str(exc), "--order") from None
            structure, theta0 = chosen.structure, chosen.theta
            notes.append(f"{sub}: base model order: {chosen.describe()}")
            if isinstance(structure, ModalStructure):
                missed = ", ".join(f"{f:.4g} Hz" for f, _, _ in structure.modes_of(theta0))
                notes.append(f"{sub}: one mode per output misses mode(s) at {missed}: the "
                             f"base model has {chosen.modes} modes (fit "
                             f"{chosen.fits[structure.base.n]:.2f} % with "
                             f"{structure.base.n})")
        # the yardstick: what a plain linear model reaches on the same split (also the
        # measure of what is reachable for the unexplained structure)
        ys = measure(data.u, data.y, est, val, float("nan"), data.fs) if yardstick else None
        sd = diagnose_data(data, sub, structure=structure, est=est, val=val, effects=effects,
                           refit=refit, max_steps=max_steps, theta0=theta0,
                           offsets=offsets, start=window[0], yardstick=ys,
                           record_meta=record.meta,
                           # a hold chosen by the linear base is asked again with the effects
                           other_hold=({"zoh": "foh", "foh": "zoh"}[choice.hold]
                                       if choice.source == "fit" else None))
        if chosen is not None:
            sd.order = chosen.to_json()
        notes += [f"{sub}: {n}" for n in sd.notes]
        from rigd.ident.sanity import model_warnings

        for st, what in ((sd.steps[0], "base model"), (sd.final, "final model")):
            if what == "final model" and len(sd.steps) == 1:
                break
            notes += [f"{sub}: {what}: WARNING: {w}" for w in model_warnings(st.structure,
                                                                            st.theta)]
        if ys is not None and ys.warning():
            notes.append(f"{sub}: base model: WARNING: {ys.warning()}")
        sd.window = window
        parts.append(sd)
    return Diagnosis(parts, record.source, notes)
