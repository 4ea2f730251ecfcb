"""design: mixed-sensitivity H∞ → balanced reduction → Tustin → controller file (paper Sec. 5)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rigd.errors import InputError


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
    from rigd.ident.modelfile import ModelFile, load_model

    if isinstance(model, ModelFile):
        return model, None
    if hasattr(model, "model") and isinstance(model.model, ModelFile):  # Identification
        return model.model, None
    return load_model(model), model


def design(model: Any, weights: str | Path = "config/design.yaml",
           out: str | Path = "controller.yaml", *, range_model: str | Path | None = None,
           report: str | Path | None = None,
           plant_at: Callable[[float, float], Any] | None = None,
           plant_at_label: str = "") -> Design:
    """Design K∞ on an identified model, check its robustness, write the controller file.

    Parameters
    ----------
    model : path, Identification or ModelFile
        Identified model with both ``actuator`` and ``bearing`` sub-models:
        G_p = G_bear·G_act (r in V -> p in µm).
    weights : path
        Design YAML: weights W_p, W_u, reduction order, prewarp frequency, robustness set-up.
    out : path
        Controller YAML to write (atomically); the loop and ``rigd ctl load`` read it.
    range_model : path, optional
        Reassembled bearing model G_bear(Ω, P_I) (:func:`rigd.api.identify_sweep`) for the
        robustness check over ``robustness.n_realizations`` random operating points, cascaded
        with the model's actuator.
    report : path, optional
        Write figures (weights, S_o, K(z)) into this directory.
    plant_at : callable(omega_rpm, p_inj_bar) -> StateSpace, optional
        Replaces ``range_model`` as the operating-range plant of the robustness check.
    plant_at_label : str
        What ``plant_at`` is, for the summary.

    Returns
    -------
    Design
        ``.K`` (discrete StateSpace), ``.summary`` (the ``--json`` object).

    Raises
    ------
    InputError
        Bad files, a model without both sub-models, no stabilising reduced controller, or
        (without an operating range) a discrete closed loop unstable on the design model.
    """
    from rigd.design import pipeline, robustness
    from rigd.design.weights import load_design_config
    from rigd.ident.modelfile import sha256_file

    cfg = load_design_config(weights)
    mf, model_path = _model_and_path(model)
    shown = str(model_path) if model_path is not None else mf.source
    G = mf.plant()
    res = pipeline.design_controller(G, cfg)
    pipeline.save_design(out, res, cfg,
                         model_hash=sha256_file(model_path) if model_path else None,
                         design_model=G,
                         note=f"designed on {Path(shown).name} at "
                              f"{mf.operating_point or 'unknown operating point'}")
    summary: dict[str, Any] = {"controller": str(out), "model": shown, **res.summary()}
    rob = None
    if range_model:
        from rigd.ident.oprange import ReassembledBearing

        gb = ReassembledBearing.load(range_model)
        Gact = mf.ss("actuator")
        rob = robustness.analyze(lambda om, p: gb.at(om, p) * Gact, res.K_z, cfg.robustness)
        summary["robustness"] = rob.summary()
        summary["robustness_model"] = f"reassembled {range_model} x actuator of {shown}"
    elif plant_at is not None:
        rob = robustness.analyze(plant_at, res.K_z, cfg.robustness)
        summary["robustness"] = rob.summary()
        summary["robustness_model"] = plant_at_label
    else:
        r, _ = robustness.assess(G, res.K_z, robustness.default_freqs(cfg.fs_hz),
                                 cfg.robustness.band_hz, cfg.robustness.low_hz)
        if not r.stable:
            raise InputError("discrete closed loop unstable on the design model", str(out))
        summary["design_point_sensitivity"] = {"reduction_min": r.reduction_min,
                                               "peak": r.peak, "peak_hz": r.peak_hz,
                                               "low_increase": r.low_increase,
                                               "lowfreq_max": r.low_increase,
                                               "reduction_at_resonance":
                                                   r.reduction_at_resonance,
                                               "resonance_hz": r.resonance_hz}
    if report:
        from rigd.design.figures import design_report

        design_report(report, cfg, res, rob, title=f"rigd design: {Path(out).name}")
        summary["report"] = str(report)
    return Design(res.K_z, res.K_red, res.K_full, res, summary)


__all__ = ["Design", "design"]
