"""design: mixed-sensitivity H∞ → fixed-order tuning or balanced reduction → Tustin →
controller file (paper Sec. 5); the work is :func:`rigd.design.workflow.design_from_model`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass
class Design:
    """A designed, checked and written controller.

    Attributes
    ----------
    K : control.StateSpace
        Discrete K∞(z) at the loop rate (Tustin), inputs e = −(p − p_eq) in µm, outputs
        [r_x, r_y] in V: the negative-feedback K of Eq. 11, as written to the controller file.
    K_continuous : control.StateSpace
        The reduced continuous K∞(s) it was discretised from.
    K_full : control.StateSpace
        The full-order H∞ controller.
    result : rigd.design.pipeline.DesignResult
        γ, orders, stability checks, band error, Hankel singular values.
    summary : dict
        The ``rigd design --json`` object (controller path, γ, orders, robustness).
    """

    K: Any
    K_continuous: Any
    K_full: Any
    result: Any
    summary: dict[str, Any]

    @property
    def path(self) -> Path:
        """The controller YAML written."""
        return Path(self.summary["controller"])


def _model_and_path(model: Any):
    from rigd.effects import resolve
    from rigd.ident.modelfile import ModelFile, load_model

    if isinstance(model, ModelFile):
        return model, None
    if hasattr(model, "model") and isinstance(model.model, ModelFile):  # Identification
        return model.model, None
    return load_model(model, resolve), model


def range_plant(model: Any, range_model: str | Path) -> Callable[[float, float], Any]:
    """The operating-range model a design is checked on: ``plant_at(Ω rpm, P_I bar)`` → G_p
    (r → p, continuous), the reassembled bearing model ``range_model`` (``g_bear.yaml``) at
    that point with the design point's bearing effects, cascaded with the identified actuator
    of ``model`` (a model file, its path, or an identification)."""
    from rigd.ident.oprange import ReassembledBearing

    mf, _ = _model_and_path(model)
    gb = ReassembledBearing.load(range_model)
    Gact = mf.ss("actuator", effects=True)
    bear = mf.submodels.get("bearing")

    def plant_at(om, p):
        Gb = gb.at(om, p)
        if bear is not None:   # the design point's bearing effects at every point
            Gb = bear.linear_ss(mf.fs, Gb)[0]
        return Gb * Gact

    return plant_at


def design(model: Any, weights: str | Path = "config/design.yaml",
           out: str | Path = "controller.yaml", *, range_model: str | Path | None = None,
           report: str | Path | None = None,
           plant_at: Callable[[float, float], Any] | None = None,
           plant_at_label: str = "", method: str | None = None,
           order: int | None = None, allow_flagged: bool = False) -> Design:
    """Design K∞ on an identified model, check its robustness, write the controller file.

    Parameters
    ----------
    model : path, Identification or ModelFile
        Identified model with both ``actuator`` and ``bearing`` sub-models:
        G_p = G_bear·G_act (r in V -> p in µm), each with the linear blocks of its effects
        (``ModelFile.plant(effects=True)``: a delay as a Padé approximant, an extra mode, lags; the
        summary's ``design_model_effects`` says which are in and why the others are not).
    weights : path
        Design YAML: weights W_p, W_u, reduction order, prewarp frequency, robustness set-up.
    out : path
        Controller YAML to write (atomically); the loop and ``rigd ctl load`` read it.
    range_model : path, optional
        Reassembled bearing model G_bear(Ω, P_I) (:func:`rigd.api.identify_sweep`) for the
        robustness check over ``robustness.n_realizations`` random operating points, cascaded
        with the model's actuator; the linear blocks of the model's bearing effects (fitted
        at its operating point) are applied at every point.
    report : path, optional
        Write figures (weights, S_o, K(z)) into this directory.
    plant_at : callable(omega_rpm, p_inj_bar) -> StateSpace, optional
        Replaces ``range_model`` as the operating-range plant of the robustness check.
    plant_at_label : str
        What ``plant_at`` is, for the summary.
    method : {"structured", "truncate"}, optional
        Overrides the design YAML's ``method`` (structured: fixed-order multi-model H∞ tuning
        on the design model and the operating range; truncate: balanced truncation of the
        full-order controller).
    order : int, optional
        Controller states (overrides ``reduction.order``).
    allow_flagged : bool
        Design even on a model with an unstable mode (default: refused). The model's sanity
        warnings (:func:`rigd.ident.sanity.file_warnings`: unstable modes, parameters at a
        bound — the latter never refuse) are in the summary (``model_warnings``) and printed
        by ``rigd design``.

    Returns
    -------
    Design
        ``.K`` (discrete StateSpace), ``.summary`` (the ``--json`` object).

    Raises
    ------
    InputError
        Bad files, a model with an unstable mode (unless ``allow_flagged``), a model without
        both sub-models, an order that cannot hold the structure
        or stabilise the design set, no stabilising reduced controller, or
        (without an operating range) a discrete closed loop unstable on the design model.
    """
    from rigd.design.workflow import design_from_model
    from rigd.errors import InputError
    from rigd.ident.modelfile import sha256_file
    from rigd.ident.sanity import file_warnings, is_unstable

    mf, model_path = _model_and_path(model)
    shown = str(model_path) if model_path is not None else mf.source
    warnings = file_warnings(mf)
    unstable = [w for w in warnings if is_unstable(w)]
    if unstable and not allow_flagged:
        more = f" (and {len(unstable) - 1} more)" if len(unstable) > 1 else ""
        raise InputError(f"model flagged by identification: {unstable[0]}{more}; refit it, "
                         "or design anyway with --allow-flagged", shown)
    if range_model:
        plant_at = range_plant(mf, range_model)
        plant_at_label = f"reassembled {range_model} x actuator of {shown}"
        carried = mf.linear_effects().get("bearing", {}).get("included", [])
        if carried:
            plant_at_label += (f", with the bearing's {', '.join(carried)} of {shown} "
                               "at every operating point")
    res, summary = design_from_model(mf, weights, out, shown=shown,
                                     model_hash=sha256_file(model_path) if model_path else None,
                                     report=report, plant_at=plant_at,
                                     plant_at_label=plant_at_label, method=method, order=order)
    summary["design_model_effects"] = mf.linear_effects()
    if warnings:
        summary["model_warnings"] = warnings
    return Design(res.K_z, res.K_red, res.K_full, res, summary)


__all__ = ["Design", "design", "range_plant"]
