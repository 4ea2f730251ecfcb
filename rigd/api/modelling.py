"""identify → compare → diagnose: grey-box models of a record and what they miss.

Plain functions over :class:`~rigd.data.record.Record` (or paths, loaded by
:func:`rigd.api.data.load`), returning result objects that carry both the python-control
models and the JSON-ready summary the ``rigd`` commands print (``../shared/DESIGN.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigd.api.data import as_record, describe_source, load
from rigd.data.record import Record
from rigd.errors import InputError
from rigd.ident.pipeline import DEFAULT_SPLIT


def parse_effects(names: str | list[str] | None, what: str = "--add") -> list[str]:
    """Effect names (``"delay,runout"`` or a list), checked against the catalogue.

    Raises
    ------
    InputError
        An unknown name (the message lists the known ones) or a name given twice
        (``rigd.effects.resolve``).
    """
    if not names:
        return []
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    from rigd.effects import resolve

    resolve(names, what)  # unknown names and names given twice
    return list(names)


def _as_model(model: Any):
    from rigd.effects import resolve
    from rigd.ident.modelfile import ModelFile, load_model

    if isinstance(model, Identification):
        return model.model
    if isinstance(model, ModelFile):
        return model
    return load_model(model, resolve)


def _data_hash(data: Any) -> str | None:
    from rigd.ident.modelfile import sha256_file

    return None if isinstance(data, Record) else sha256_file(data)


def _yardstick_json(ys: dict[str, Any]) -> dict[str, Any]:
    """``{"generic": {...}}`` (per sub-model) of :class:`rigd.ident.yardstick.Yardstick`s."""
    return {n: (y.to_json() if y is not None else None) for n, y in ys.items()}


# --- identify ------------------------------------------------------------------------------
@dataclass
class Identification:
    """An identified model file in memory, with the numbers ``rigd identify`` prints.

    Attributes
    ----------
    model : rigd.ident.modelfile.ModelFile
        Sub-models (``actuator`` Eqs. 8–10, ``bearing`` Eqs. 5–7, or ``generic``) with their
        parameters, standard deviations, fits and read-outs.
    effects : list of str
        Effects added to the structure (``--add``).
    source : dict
        Where the record came from (:func:`rigd.api.data.describe_source`).
    """

    model: Any
    effects: list[str] = field(default_factory=list)
    source: dict[str, Any] = field(default_factory=dict)
    #: per sub-model: what a plain ARX and a subspace model reach on the same split
    #: (:class:`rigd.ident.yardstick.Yardstick`, None when the split does not allow it)
    yardstick: dict[str, Any] = field(default_factory=dict)

    @property
    def submodels(self) -> list[str]:
        return list(self.model.submodels)

    @property
    def fit_percent(self) -> float | dict[str, float]:
        """Validation fit, %: 100·(1 − NRMSE), mean over outputs (a dict per sub-model)."""
        fp = {n: sm.fit_percent["validation_mean"] for n, sm in self.model.submodels.items()}
        return next(iter(fp.values())) if len(fp) == 1 else fp

    @property
    def parameters(self) -> dict[str, Any]:
        """Physical parameters by name (SI units of the structure; per sub-model if several)."""
        p = {n: sm.parameters for n, sm in self.model.submodels.items()}
        return next(iter(p.values())) if len(p) == 1 else p

    def ss(self, submodel: str | None = None):
        """Continuous python-control ``StateSpace`` of a sub-model (inputs V, outputs µm/V).

        ``submodel`` may be omitted when the model has only one.
        """
        if submodel is None:
            if len(self.model.submodels) != 1:
                raise InputError("give the sub-model: this model has "
                                 + ", ".join(self.model.submodels))
            submodel = next(iter(self.model.submodels))
        return self.model.ss(submodel)

    def plant(self):
        """G_p(s) = G_bear(s)·G_act(s) (Eq. 11 plant): r = [r_x, r_y] in V -> [e_x, e_y] in µm."""
        return self.model.plant()

    def save(self, path: str | Path) -> Path:
        """Write the model file (YAML, atomically)."""
        return self.model.save(path)

    def summary(self) -> dict[str, Any]:
        """The ``rigd identify --json`` object (DESIGN.md contract, plus ``source``)."""
        from rigd.plain import plain

        subs = self.model.submodels
        if len(subs) == 1:
            (_, sm), = subs.items()
            fp: Any = sm.fit_percent["validation_mean"]
            params: Any = sm.parameters
            std: Any = {n: float(s) for n, s in zip(sm.structure.names, sm.std)}
            ro: Any = sm.readouts
        else:
            fp = {n: sm.fit_percent["validation_mean"] for n, sm in subs.items()}
            params = {n: sm.parameters for n, sm in subs.items()}
            std = {n: {p: float(s) for p, s in zip(sm.structure.names, sm.std)}
                   for n, sm in subs.items()}
            ro = {n: sm.readouts for n, sm in subs.items()}
        return {"fit_percent": fp, "parameters": params, "effects": list(self.effects),
                "std": std, "readouts": plain(ro),
                "fit_percent_per_output": {n: sm.fit_percent for n, sm in subs.items()},
                "split": self.model.split, "operating_point": self.model.operating_point,
                "yardstick": _yardstick_json(self.yardstick),
                "source": self.source}


def identify(data: Record | str | Path, submodels: str | list[str] = "auto", *,
             runout: Record | str | Path | None = None, add: str | list[str] | None = None,
             method: str = "auto", init: Any = None, split: float | None = None,
             est: str | slice | None = None, val: str | slice | None = None,
             hold: str = "auto", offsets: bool = True, median: bool = True,
             runout_filter: bool = True, offset_samples: int = 2000,
             out: str | Path | None = None, order: str | int = "auto",
             yardstick: bool = True, **load_kw: Any) -> Identification:
    """Identify grey-box models of a record by the prediction-error method (paper Sec. 4).

    Parameters
    ----------
    data : Record or path
        The record; a path is loaded by :func:`rigd.api.data.load` with ``load_kw``
        (``fs``, ``inputs``, ``outputs`` for a plain CSV, ``range``).
    submodels : {"auto", "both", "actuator", "bearing", "generic"} or list of str
        What to identify (``auto``: all the record's columns allow).
    runout : Record or path, optional
        Run-out record at the same operating point (needs ``phi``): run-out filter F_r(φ).
    add : str or list of str, optional
        Effects (``rigd.effects.REGISTRY``) added to the structure, e.g. ``["delay"]``.
    method : {"auto", "pem", "oe"}
        Prediction error (one-step predictor) or output error; ``auto``: prediction error
        for the rotor's actuator and bearing (the paper's method), output error for a
        generic record (its held-out figure is a free-run simulation, as every peer tool's;
        :func:`diagnose`'s default, so its base model is this one).
    init : Identification, ModelFile or path, optional
        Start from this model's parameters.
    split : float, optional
        Fraction of samples used for estimation; the rest validates (default 2/3); not with
        ``est``/``val``.
    est, val : "A:B" or slice, optional
        Estimation and validation samples (both or neither, each at least 100 samples; as
        :func:`diagnose`): fitted on ``est``, fit reported on both.
    hold : {"auto", "zoh", "foh"}
        Inputs between samples (``auto``: declared by the record, known for rigd
        recordings, else chosen from the data; docs/identify.md).
    offsets, median, runout_filter : bool
        Prefilters of §4.4: offset removal (mean of the first ``offset_samples``), median
        filter on e_x, e_y, run-out filter (with ``runout``).
    out : path, optional
        Write the model file here.
    order : "auto" or int
        Generic records: modes of the base model, or ``auto`` (chosen from the data,
        :func:`rigd.ident.greybox.order.choose_order`).
    yardstick : bool
        Fit a plain ARX and a subspace model on the same split and report what they reach
        (``.yardstick``, ``"yardstick"`` in the JSON; docs/diagnose.md "Yardstick").

    Returns
    -------
    Identification
        ``.model`` (model file), ``.ss(name)`` / ``.plant()`` (python-control StateSpace),
        ``.fit_percent`` (%), ``.parameters``, ``.summary()`` (the ``--json`` object).
    """
    from rigd.diagnose.added import refit_as_diagnosed
    from rigd.effects import resolve
    from rigd.ident.prefilter import PrefilterOptions
    from rigd.ident.workflow import identify_record

    effects = parse_effects(add)
    est_s, val_s = _est_val(est, val, split)
    if offset_samples <= 0:
        raise InputError("--offset-samples must be positive", "--offset-samples")
    options = PrefilterOptions(offsets=offsets, median=median, runout=runout_filter,
                               offset_samples=offset_samples)
    record = as_record(data, **load_kw)
    _check_parts(est_s, val_s, record.n)
    ro = as_record(runout) if runout is not None else None
    model = identify_record(record, submodels, runout=ro, options=options, method=method,
                            init=_as_model(init) if init is not None else None,
                            effects=resolve(effects),
                            split=DEFAULT_SPLIT if split is None else split,
                            est=est_s, val=val_s, data_hash=_data_hash(data),
                            hold=hold, order=order, refit=refit_as_diagnosed)
    if out:
        model.save(out)
    ys = {}
    if yardstick:
        from rigd.ident.compare import yardsticks

        ys = yardsticks(model, record, ro, {n: sm.fit_percent["validation_mean"]
                                            for n, sm in model.submodels.items()})
    return Identification(model, effects, describe_source(record.meta), ys)


def identify_sweep(run_dir: str | Path, *, out: str | Path | None = None,
                   jobs: int | None = None, method: str = "auto", split: float | None = None,
                   offsets: bool = True, median: bool = True, runout_filter: bool = True,
                   offset_samples: int = 2000):
    """Identify every point of a sweep run directory; reassemble G_bear(Ω, P_I).

    Parameters
    ----------
    run_dir : path
        A ``rigd experiment`` sweep run directory (``manifest.json``).
    out : path, optional
        Reassembled bearing model file (default ``run_dir/g_bear.yaml``).
    jobs : int, optional
        Parallel processes (default: all cores).

    Returns
    -------
    rigd.ident.oprange.SweepResult
        ``.points`` (per point fits and modes), ``.gbear`` (``.at(Ω_rpm, P_I_bar)`` ->
        StateSpace), ``.summary()`` (with ``source`` from the manifest), ``.text()``.
    """
    from rigd.data.manifest import read_manifest
    from rigd.ident.oprange import identify_sweep as _sweep
    from rigd.ident.prefilter import PrefilterOptions

    if offset_samples <= 0:
        raise InputError("--offset-samples must be positive", "--offset-samples")
    options = PrefilterOptions(offsets=offsets, median=median, runout=runout_filter,
                               offset_samples=offset_samples)
    res = _sweep(run_dir, out=out, jobs=jobs, method=method, options=options,
                 split=DEFAULT_SPLIT if split is None else split)
    try:
        res.source = describe_source(read_manifest(run_dir))
    except InputError:
        res.source = describe_source({})
    return res


# --- compare -------------------------------------------------------------------------------
@dataclass
class ComparisonResult:
    """Model vs record, per sub-model (:class:`rigd.ident.compare.Comparison`).

    Attributes
    ----------
    comparisons : dict
        Sub-model name -> Comparison (``.data``, ``.yhat`` simulated outputs, ``.fit`` per
        output, %, ``.residual`` statistics).
    source : dict
        Where the record came from.
    report : str or None
        HTML report directory, if one was written.
    warnings : list of str
        The model's sanity warnings (unstable mode, parameter at a bound;
        :func:`rigd.ident.sanity.file_warnings`), each prefixed by its sub-model: the fit of
        such a model is shown, not trusted.
    """

    comparisons: dict[str, Any]
    source: dict[str, Any] = field(default_factory=dict)
    report: str | None = None
    warnings: list[str] = field(default_factory=list)
    #: ``part="validation"``: per sub-model, what a plain ARX and a subspace model reach
    #: on the same split (:class:`rigd.ident.yardstick.Yardstick`)
    yardstick: dict[str, Any] = field(default_factory=dict)

    @property
    def fit_percent(self) -> float | dict[str, float]:
        """Mean fit over outputs, % (a dict per sub-model if several)."""
        fp = {n: float(np.mean(c.fit)) for n, c in self.comparisons.items()}
        return next(iter(fp.values())) if len(fp) == 1 else fp

    def summary(self) -> dict[str, Any]:
        """The ``rigd compare --json`` object (plus ``source``)."""
        from rigd.ident.compare import summary

        res = summary(self.comparisons)
        if self.report:
            res["report"] = self.report
        res["warnings"] = list(self.warnings)
        if self.yardstick:
            res["yardstick"] = _yardstick_json(self.yardstick)
        res["source"] = self.source
        return res


def compare(model: Any, data: Record | str | Path, *,
            runout: Record | str | Path | None = None, part: str = "all",
            x0: str = "estimation",
            report: str | Path | None = None, title: str | None = None,
            yardstick: bool = True, **load_kw: Any) -> ComparisonResult:
    """Simulate a model on a record: fit per output and residual statistics.

    Parameters
    ----------
    model : Identification, ModelFile or path
        The identified model (``rigd identify`` output).
    data : Record or path
        Held-out record (or use ``part="validation"`` on the identification record); a path
        is loaded with ``load_kw`` (``fs``, ``inputs``, ``outputs``, ``range``).
    runout : Record or path, optional
        Run-out record for the run-out filter.
    part : {"all", "validation", "estimation"}
        Which part of the record (the model's split) to compare.
    x0 : {"estimation", "estimate"}
        ``part="validation"``: the initial state (and output offsets) from the estimation
        part (default: nothing fitted on the held-out samples, the figure other tools
        give), or ``"estimate"``: re-estimated on the validation samples themselves
        (labelled so in ``summary()["initial_state"]``). Other parts: estimated on the
        compared samples.
    yardstick : bool
        With ``part="validation"`` and the default ``x0``: fit a plain ARX and a subspace
        model on the model's estimation part and report what they reach on its validation
        part (``.yardstick``; a warning when the model is worse).
    report : path, optional
        Write the report into this directory: ``index.html``, interactive (measured vs
        simulated, residual spectrum, by amplitude and angle; :mod:`rigd.diagnose.compare_page`),
        and ``figures.html`` with the PNG figures.

    Returns
    -------
    ComparisonResult
        ``.warnings``: the model's sanity warnings (unstable mode, parameter at a bound)
        and a fit below 0 % or diverged (:func:`rigd.ident.compare.fit_warnings`),
        printed by ``rigd compare`` and in its JSON: such a model is compared, never
        silently (``rigd design`` refuses it).
    """
    from rigd.diagnose.compare_page import write_compare_page
    from rigd.ident.compare import compare_model, fit_warnings
    from rigd.ident.sanity import file_warnings

    if report:
        from rigd.htmlpage import report_dir

        report_dir(report)
    mf = _as_model(model)
    record = as_record(data, **load_kw)
    ro = as_record(runout) if runout is not None else None
    comps = compare_model(mf, record, ro, part, x0)
    warnings = [w for w in file_warnings(mf) if w.split(":", 1)[0] in comps]
    warnings += fit_warnings(comps)  # a fit below 0 % or diverged: flagged, never read as one
    ys = {}
    if yardstick and part == "validation" and x0 == "estimation":
        from rigd.ident.compare import yardsticks

        ys = yardsticks(mf, record, ro, {n: float(np.mean(c.fit)) for n, c in comps.items()})
        warnings += [f"{n}: {y.warning()}" for n, y in ys.items()
                     if y is not None and y.warning()]
    res = ComparisonResult(comps, describe_source(record.meta), warnings=warnings,
                           yardstick=ys)
    if report:
        res.report = str(write_compare_page(comps, report, title or f"{mf.source} vs "
                                            f"{record.source}", warnings=warnings))
    return res


# --- diagnose ------------------------------------------------------------------------------
@dataclass
class DiagnosisResult:
    """Where the model fails and which physical effect is missing (docs/diagnose.md).

    Attributes
    ----------
    diagnosis : rigd.diagnose.diagnosis.Diagnosis
        One part per sub-model: findings (effect, significance, score, fit with it),
        what the record cannot reveal, what stays unexplained, the forward-selection steps.
    source : dict
    report : str or None
    """

    diagnosis: Any
    source: dict[str, Any] = field(default_factory=dict)
    report: str | None = None
    #: where ``save_model`` wrote the final model (a model file), or None
    saved_model: str | None = None

    def summary(self) -> dict[str, Any]:
        """The ``rigd diagnose --json`` object (DESIGN.md contract, plus ``source``)."""
        out = self.diagnosis.to_json()
        if self.report:
            out["report"] = self.report
        if self.saved_model:
            out["saved_model"] = self.saved_model
        out["source"] = self.source
        return out

    @property
    def significant(self) -> list[str]:
        """Names of the significant effects, most likely first."""
        return [f["effect"] for f in self.diagnosis.to_json()["findings"] if f["significant"]]


def _sample_range(s: str | slice | None, what: str) -> slice | None:
    if s is None or isinstance(s, slice):
        return s
    try:
        a, b = s.split(":")
        return slice(int(a) if a else None, int(b) if b else None)
    except ValueError:
        raise InputError(f"{what} must be START:STOP sample indices, got {s!r}",
                         f"--{what}") from None


def _est_val(est: str | slice | None, val: str | slice | None,
             split: float | None) -> tuple[slice | None, slice | None]:
    """``--est``/``--val`` as slices, checked against each other and ``--split`` (the one
    rule of ``identify`` and ``diagnose``)."""
    est_s, val_s = _sample_range(est, "est"), _sample_range(val, "val")
    if (est_s is None) != (val_s is None):
        raise InputError("give both --est and --val, or neither", "--est/--val")
    if split is not None and est_s is not None:
        raise InputError("give --split or --est/--val, not both", "--split")
    return est_s, val_s


def _check_parts(est: slice | None, val: slice | None, n: int) -> None:
    """Each of ``--est``/``--val`` selects at least 100 of the record's ``n`` samples."""
    if est is None:
        return
    for s, what in ((est, "est"), (val, "val")):
        if s.step not in (None, 1):
            raise InputError(f"{what} range must be START:STOP without a step", f"--{what}")
        a, b = s.indices(n)[:2]
        if b - a < 100:
            raise InputError(f"{what} range has {max(b - a, 0)} samples of {n}; need "
                             "at least 100", f"--{what}")


def diagnose(data: Record | str | Path, *, runout: Record | str | Path | None = None,
             submodels: list[str] | None = None, est: str | slice | None = None,
             val: str | slice | None = None, split: float | None = None,
             effects: str | list[str] | None = None, refit: bool = True, hold: str = "auto",
             steps: int = 3, report: str | Path | None = None, order: str | int = "auto",
             method: str = "oe", init: Any = None, save_model: str | Path | None = None,
             model: Any = None, **load_kw: Any) -> DiagnosisResult:
    """Diagnose a record: residual analysis, catalogue signatures, forward selection.

    Parameters
    ----------
    data : Record or path
        The record; a path is loaded with ``load_kw`` (``fs``, ``inputs``, ``outputs``,
        ``range``).
    runout : Record or path, optional
        Run-out record at the same operating point (run-out filter, §4.4).
    submodels : list of {"actuator", "bearing", "generic"}, optional
        Default: all the record supports.
    est, val : "A:B" or slice, optional
        Estimation and validation samples (both or neither); default: ``split``.
    split : float, optional
        Estimation fraction (default 2/3, as :func:`identify`); not with ``est``/``val``.
    effects : str or list of str, optional
        Only test these catalogue effects.
    refit : bool
        Refit with each effect added (``fit_percent_with``); False: signature tests only.
    hold : {"auto", "zoh", "foh"}
    steps : int
        Most effects added one after another (forward selection).
    report : path, optional
        Write the report page into this directory.
    order : "auto" or int
        Generic records: modes of the base model (as :func:`identify`).
    method : {"oe", "pem"}
        Fit method of the base model and of every refit (default output error: the base
        model is then :func:`identify`'s — for a generic record with its default
        ``method="auto"``, for the rotor's sub-models with ``method="oe"``;
        rigd.ident.pipeline).
    init : Identification, ModelFile or path, optional
        Start the base fit from this model's parameters (as :func:`identify`).
    model : Identification, ModelFile or path, optional
        Diagnose this model on the record: it is the base, not refitted (only its initial
        state and output offsets are estimated here); the same structure refitted here
        says in words what moved (``given_model`` in the JSON; :mod:`rigd.diagnose.given`).
        Not with ``init``.
    save_model : path, optional
        Write the model the forward selection ends with (the base and the effects it added,
        as fitted) as a model file (``rigd identify -o``'s format, written atomically):
        ``rigd compare``, ``rigd design`` and ``--init`` read it
        (:mod:`rigd.diagnose.save`).

    Returns
    -------
    DiagnosisResult
        ``.summary()`` is the ``rigd diagnose --json`` object; ``.significant`` the names.
    """
    from rigd.diagnose.diagnosis import diagnose_record

    est_s, val_s = _est_val(est, val, split)
    names = None
    if effects:
        names = parse_effects(effects, "--effects")
    if steps < 1:
        raise InputError(f"--steps must be at least 1 (got {steps})", "--steps")
    if report:
        from rigd.htmlpage import report_dir

        report_dir(report)
    rec = as_record(data, **load_kw)
    ro = as_record(runout) if runout is not None else None
    _check_parts(est_s, val_s, rec.n)
    from rigd.ident.pem import METHODS as FIT_METHODS

    if method not in FIT_METHODS:
        raise InputError(f"unknown fit method {method!r} (known: oe, pem)", "--method")
    if model is not None and init is not None:
        raise InputError("--model diagnoses a given model, --init fits a new one from it: "
                         "use one of them", "--model")
    diag = diagnose_record(rec, runout=ro, submodels=submodels, est=est_s, val=val_s,
                           effects=names, refit=refit, hold=hold, split=split,
                           max_steps=steps, order=order, method=method,
                           init=_as_model(init) if init is not None else None,
                           model=_as_model(model) if model is not None else None,
                           model_path=str(model) if isinstance(model, (str, Path))
                           else "the given model")
    res = DiagnosisResult(diag, describe_source(rec.meta))
    if save_model:
        from rigd.diagnose.save import diagnosis_model_file

        mf = diagnosis_model_file(diag, rec, _data_hash(data))
        mf.save(save_model)
        res.saved_model = str(save_model)
    if report:
        from rigd.diagnose.report_page import write_report

        res.report = str(write_report(diag, report))
    return res


__all__ = ["ComparisonResult", "DiagnosisResult", "Identification", "compare", "diagnose",
           "identify", "identify_sweep", "load", "parse_effects"]
