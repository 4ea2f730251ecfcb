"""The model a diagnosis ends with, as a model file (``rigd diagnose --save-model``).

The forward selection (:mod:`rigd.diagnose.engine`) ends with the base model and the
significant effects it added, refitted together on the estimation part. That model is what
the diagnosis measured ("error falls: base 83.6 % -> +cubic_stiffness 98.4 %"); this module
writes it as ``rigd identify -o`` writes a model (:func:`rigd.ident.workflow.model_file`: the
same prefilters, split, read-outs, fits and residual statistics), so that ``rigd compare``,
``rigd design`` and ``rigd identify --init`` use exactly what the diagnosis fitted, without
refitting it from other start values.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from rigd.errors import InputError


def diagnosis_model_file(diagnosis: Any, record: Any, data_hash: str | None = None):
    """:class:`rigd.ident.modelfile.ModelFile` of the final model of every sub-model of
    ``diagnosis`` (:class:`rigd.diagnose.diagnosis.Diagnosis`) diagnosed on ``record``.

    The parameters are the last step's, kept as fitted (no further iteration); their
    standard deviations come from the Jacobian at them on the estimation part
    (:func:`rigd.ident.pem.evaluate`), as a fit reports them.

    Raises
    ------
    InputError
        A sub-model diagnosed without its base fit (``--no-refit`` keeps no model to save).
    """
    from rigd.ident.pem import evaluate
    from rigd.ident.pipeline import DEFAULT_SPLIT
    from rigd.ident.workflow import model_file

    fitted = []
    for sd in diagnosis.parts:
        bf = sd.base_fit
        if bf is None or not sd.steps:
            raise InputError(f"{sd.submodel}: the diagnosis kept no fitted model to save",
                             "--save-model")
        step = sd.final
        res = evaluate(step.structure, bf.est_data, step.theta,
                       status="diagnose: the forward selection's final model, kept as fitted")
        res = dataclasses.replace(res, method=bf.settings.method)
        fitted.append((bf, step.structure, res))
    split = (bf.settings.split or DEFAULT_SPLIT) if bf.settings.est is None else None
    return model_file(record, fitted, data_hash, split)
