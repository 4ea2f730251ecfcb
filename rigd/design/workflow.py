"""``rigd design`` as a function: model file + weights → controller file, summary, report.

:func:`design_from_model` is what :func:`rigd.api.design` (``rigd design``, the demo) calls on
a loaded model and operating-range model; it runs :func:`rigd.design.pipeline.design`,
writes the controller file, assesses robustness over the operating range for the chosen
design and — for the structured design — for the truncated full-order design beside it
(``comparison`` in the summary), and writes the figures.
"""

from __future__ import annotations

from pathlib import Path


def _side(res, rob, set_gamma) -> dict:
    d = {"method": res.method, "controller_order": res.order,
         "gamma": max(r["gamma"] for r in set_gamma), "gamma_per_model": set_gamma,
         "band_error": res.band_error,
         "controller_gain_1hz_over_band_max": res.lowfreq_gain_ratio,
         "closed_loop_stable_design_model": res.stable_discrete}
    if rob is not None:
        s = rob.summary()
        d.update({k: s[k] for k in (
            "all_stable", "sensitivity_peak_max", "sensitivity_peak_hz",
            "sensitivity_lowfreq_max", "sensitivity_reduction_min",
            "sensitivity_reduction_at_resonance_min",
            "sensitivity_reduction_at_resonance_mode_direction_min",
            "disturbance_peak_reduction_min")})
        d["reduction_at_resonance_per_realization"] = [
            {"omega_rpm": r.omega_rpm, "p_inj_bar": r.p_inj_bar, "resonance_hz": r.resonance_hz,
             "sigma_max": r.reduction_at_resonance, "mode_direction": r.reduction_at_resonance_mode}
            for r in rob.realizations]
    return d


def design_from_model(mf, weights_path, out, *, shown: str = "model",
                      model_hash: str | None = None, report=None, plant_at=None,
                      plant_at_label: str = "", method: str | None = None,
                      order: int | None = None):
    """Design, check and write; returns (DesignResult, summary dict).

    Parameters
    ----------
    mf : object with ``plant(effects=)`` and ``operating_point``
        The identified model (a ``ModelFile``, loaded by the caller: ``rigd.design`` reads no
        model files) with G_p = G_bear·G_act, designed on with the linear blocks of its
        sub-models' effects (``ModelFile.plant(effects=True)``).
    weights_path : path
        Design YAML (:class:`rigd.design.weights.DesignConfig`).
    out : path
        Controller YAML to write (atomically, after the checks).
    shown, model_hash : str
        How the model is named in the summary and the controller note; its file's hash.
    plant_at : callable, optional
        ``plant_at(Ω rpm, P_I bar) -> G_p(s)`` over the operating range (the reassembled
        G_bear × the actuator, or the simulated plant's truth in ``demo --quick``): the
        structured design set and the robustness check; ``plant_at_label`` names it.
    method, order : optional
        Override ``method`` and ``reduction.order`` of the design YAML.
    """
    from rigd.design import pipeline, robustness
    from rigd.design.weights import load_design_config
    from rigd.errors import InputError

    cfg = load_design_config(weights_path)
    G = mf.plant(effects=True)   # with the linear blocks of the effects it names
    label = plant_at_label
    res, cmp = pipeline.design(G, cfg, method=method, order=order, plant_at=plant_at)
    pipeline.save_design(out, res, cfg,
                         model_hash=model_hash,
                         design_model=G,
                         note=f"{res.method} design of order {res.order} on "
                              f"{Path(shown).name} at "
                              f"{mf.operating_point or 'unknown operating point'}")
    summary = {"controller": str(out), "model": shown, **res.summary()}
    rob = rob_cmp = None
    if plant_at is not None:
        rob = robustness.analyze(plant_at, res.K_z, cfg.robustness)
        summary["robustness"] = rob.summary()
        summary["robustness_model"] = label
        if cmp is not None:
            rob_cmp = robustness.analyze(plant_at, cmp.K_z, cfg.robustness)
    else:
        r, _sig = robustness.assess(G, res.K_z, robustness.default_freqs(cfg.fs_hz),
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
    if cmp is not None:
        from rigd.design.structured_design import gamma_on_set

        summary["comparison"] = {
            d.method: _side(d, r, gamma_on_set(G, cfg, d.K_z, plant_at))
            for d, r in ((res, rob), (cmp, rob_cmp))}
    if report:
        from rigd.design.figures import design_report

        design_report(report, cfg, res, rob, title=f"rigd design: {Path(out).name}",
                      comparison=summary.get("comparison"),
                      comparison_failed=res.comparison_failed)
        summary["report"] = str(report)
    return res, summary
