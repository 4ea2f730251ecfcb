"""The demo's modelling step: identify, diagnose, add what is named, watch the error fall.

What a researcher does by hand with ``rigd identify``, ``rigd diagnose``, ``rigd identify
--add`` and ``rigd compare`` (docs/diagnose.md), on the demo's design-point records:

1. the plain grey-box models (actuator, bearing; Eqs. 4-8) of the identification PRBS;
2. ``diagnose`` of the same record with the same fit settings (:func:`rigd.api.diagnose`,
   ``method="pem"`` as the demo identifies, so its base model *is* the plain model): the
   effects its forward selection adds are the ones named, per sub-model;
3. each sub-model identified again with the effects named for it (``identify --add``);
4. both models compared on a held-out record (another PRBS seed at the same operating point,
   never used in any fit): the validation fit per sub-model before and after.

Nothing here knows the plant: what is named is what the shared diagnosis says.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from rigd.api.modelling import compare, diagnose

SUBMODELS = ("actuator", "bearing")
METHOD = "pem"


@dataclass
class ModelStory:
    """What the modelling step found and fitted.

    Attributes
    ----------
    base, improved : rigd.ident.modelfile.ModelFile
        The plain models and the models with the named effects (the design's).
    named : dict
        Sub-model -> effect names the diagnosis added, in its order of addition.
    fit_before, fit_after : dict
        Sub-model -> fit on the held-out record, %, mean over outputs (base, improved).
    diagnosis : dict
        The ``rigd diagnose --json`` object of the identification record.
    before, after : rigd.api.modelling.ComparisonResult
        The held-out comparisons (their ``.comparisons`` carry the simulated outputs).
    extra : list of str
        Effects added on request (``rigd demo --add``) beyond the named ones.
    """

    base: Any
    improved: Any
    named: dict[str, list[str]]
    fit_before: dict[str, float]
    fit_after: dict[str, float]
    diagnosis: dict[str, Any]
    before: Any
    after: Any
    extra: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """``summary.json``'s ``diagnosis`` object."""
        d = self.diagnosis
        flat = list(dict.fromkeys(n for s in SUBMODELS for n in self.named.get(s, [])))
        return {
            "named": flat,
            "named_by_submodel": {s: list(self.named.get(s, [])) for s in SUBMODELS},
            "fit_before": dict(self.fit_before),
            "fit_after": dict(self.fit_after),
            "held_out": "a PRBS of another seed at the design point, used in no fit; "
                        "fit = 100·(1 − NRMSE), mean over outputs",
            "method": METHOD,
            "diagnosis_fit_percent": d.get("fit_percent"),
            "steps": d.get("steps"),
            "findings": [{k: f.get(k) for k in ("effect", "submodel", "significant", "score",
                                                 "fit_percent_with", "explanation")}
                         for f in d.get("findings", [])],
            "unexplained": [{"submodel": u.get("submodel"), "text": u.get("text")}
                            for u in d.get("unexplained", [])],
            "extra_effects": list(self.extra),
        }


def named_effects(diag_json: dict[str, Any]) -> dict[str, list[str]]:
    """Sub-model -> the effects the diagnosis' forward selection added (its ``steps``)."""
    steps = diag_json.get("steps") or {}
    if isinstance(steps, list):  # one sub-model examined
        only = next(iter(diag_json.get("tests") or {}), None)
        steps = {only: steps} if only else {}
    return {s: [st["added"] for st in steps.get(s, []) if st.get("added")] for s in SUBMODELS}


def _fits(comp) -> dict[str, float]:
    return {n: float(np.mean(c.fit)) for n, c in comp.comparisons.items()}


def _with_effects(record, runout, base, named: dict[str, list[str]], extra: list[str]):
    """``base`` with each sub-model refitted with its named effects (and ``extra``), each
    refitted as the diagnosis refits it (``rigd identify --add``'s refit,
    :func:`rigd.diagnose.added.refit_as_diagnosed`)."""
    from rigd.diagnose.added import refit_as_diagnosed
    from rigd.effects import resolve
    from rigd.ident.workflow import identify_record

    subs, pre = dict(base.submodels), dict(base.prefilters)
    for s in SUBMODELS:
        names = list(dict.fromkeys(named.get(s, []) + extra))
        effects = [e for e in resolve(names, "--add") if s in e.submodels]
        if not effects:
            continue
        m = identify_record(record, [s], runout=runout, method=METHOD, effects=effects,
                            refit=refit_as_diagnosed)
        subs[s] = m.submodels[s]
        pre.update(m.prefilters)
    return replace(base, submodels=subs, prefilters=pre)


def model_story(record, runout, heldout, base, out: Path, *,
                extra: list[str] | None = None, say=print) -> ModelStory:
    """Diagnose ``record`` (with ``runout``), add what is named to ``base``, compare both on
    ``heldout``; reports into ``out/diagnose``, ``out/compare_before``, ``out/compare_after``.

    Parameters
    ----------
    record, runout, heldout : rigd.data.record.Record
        Identification PRBS, run-out record, held-out PRBS (same operating point).
    base : rigd.ident.modelfile.ModelFile
        The plain models of ``record`` (``identify_record(record, "both", runout=runout)``).
    out : path
        Demo output directory.
    extra : list of str, optional
        Effects added beyond the named ones (``rigd demo --add``), to every sub-model they
        concern.
    say : callable
        Progress lines.
    """
    extra = list(extra or [])
    diag = diagnose(record, runout=runout, method=METHOD, report=out / "diagnose").summary()
    named = named_effects(diag)
    for s in SUBMODELS:
        say(f"      {s}: diagnose names {', '.join(named[s]) or 'nothing'}")
    improved = _with_effects(record, runout, base, named, extra)
    before = compare(base, heldout, runout=runout, part="all", yardstick=False,
                     report=out / "compare_before",
                     title="plain models on the held-out record")
    after = compare(improved, heldout, runout=runout, part="all", yardstick=False,
                    report=out / "compare_after",
                    title="models with the named effects on the held-out record")
    return ModelStory(base, improved, named, _fits(before), _fits(after), diag, before, after,
                      extra)


__all__ = ["ModelStory", "model_story", "named_effects"]
