"""run_demo: the whole story in lock-step on the simulated rig (``rigd demo``, ``make demo``).

The default plant is the physics-grade one (``config/sim_reynolds.yaml``: Reynolds film,
orifices, flexible shaft), whose structure is not the grey-box model class, so the
modelling step has something to find:

1. records (:func:`rigd.api.run_experiment`): PRBS, a held-out PRBS of another seed and a
   run-out record at the design point (Ω = 4000 rpm, P_I = 7 bar), and a PRBS sweep over a
   small (Ω, P_I) grid;
2. models (:mod:`rigd.api.demo_model`): the plain actuator and bearing models, ``diagnose``
   of the identification record, each sub-model refitted with the effects named for it, both
   compared on the held-out record (the error falling); the reassembled bearing model
   G_bear(Ω, P_I) from the sweep;
3. design (:func:`rigd.api.design`) on the improved model — its G_p carries the linear
   block of each named effect that has one (a delay as a Padé approximant, an extra mode;
   ``design_model_effects`` in the summary says which, and why the others are left out) —:
   H∞, reduction, Tustin, robustness over 30 random operating points of the reassembled
   model (with the design point's bearing effects) cascaded with the identified actuator;
4. deploy: the controller file is loaded by the loop (validated, closed loop re-checked);
5. proof: impacts K∞ off/on at Ω = 0, P_I = 4 and 7 bar, both axes
   (:func:`rigd.api.analyze_impact`);
6. ``DIR/summary.json`` and ``DIR/index.html``, the story with every figure
   (:mod:`rigd.api.demo_page`).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

from rigd.api.design import design as run_design
from rigd.api.experiment import run_experiment
from rigd.api.impact import analyze_impact
from rigd.errors import InputError

DESIGN_POINT = (4000.0, 7.0)
IMPACT_POINTS = (4.0, 7.0)
GRID = {"omega_rpm": [0.0, 6000.0], "p_inj_bar": [3.0, 5.0, 7.0]}
QUICK_GRID = {"omega_rpm": [0.0, 6000.0], "p_inj_bar": [3.0, 7.0]}
DEFAULT_CONFIG = "config/sim_reynolds.yaml"


def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _experiment(spec: dict, config: str, run_dir: Path, controller=None) -> None:
    res = run_experiment(spec, config=config, lockstep=True, out=run_dir, controller=controller)
    if not res.ok:
        raise InputError(f"experiment {spec.get('name')} ended {res.status}: {res.message}",
                         str(run_dir))


def run_demo(out: str | Path, *, config: str = DEFAULT_CONFIG,
             weights: str = "config/design.yaml", quick: bool = False,
             jobs: int = 2, add: list[str] | None = None) -> dict[str, Any]:
    """The whole story in lock-step on the simulated rig; returns ``summary.json``'s dict.

    Parameters
    ----------
    out : path
        Output directory (records, model files, controller, reports, ``summary.json``).
    config : path
        Simulated rig configuration (default the physics-grade plant, ``sim_reynolds``).
    weights : path
        Design YAML (W_p, W_u, reduction, robustness).
    quick : bool
        For tests: the same steps with shorter records and one impact per state; the
        operating range from a 2 × 2 sweep, or on the ``sim`` plant its truth (no sweep).
    jobs : int
        Processes for the sweep fits.
    add : list of str, optional
        Catalogue effects (``rigd.effects``) added to the design-point models beside the ones
        ``diagnose`` names (to every sub-model they concern).

    Returns
    -------
    dict
        ``summary.json``: γ, controller order, sensitivity figures over the operating range,
        damping ratios ζ open/closed per impact (keys ``P<bar>bar_W<rpm>rpm_<axis>``),
        identification fits (%) of the design's models, ``diagnosis`` (what was named per
        sub-model, held-out fits before and after adding it), ``design_model_effects`` (per
        sub-model the effects whose linear block the design model carries and those left
        out, with why), timings (s).
    """
    from rigd.api.demo_model import model_story
    from rigd.api.demo_page import write_index
    from rigd.data import load_record
    from rigd.ident.workflow import identify_record
    from rigd.rigconfig import load_config

    effects = None
    if add:
        from rigd.effects import resolve

        effects = resolve(add, "--add")   # one line naming the unknown ones, before any work
    plant = load_config(config).config.drivers.fast.name
    truth = quick and plant == "sim"     # the paper's plant: its operating range is known
    t_start = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    timings = {}
    om, p = DESIGN_POINT
    dur = 1.5 if quick else 3.0

    # 1. records at the design point
    t0 = time.perf_counter()
    _say(f"[1/6] PRBS, held-out PRBS and run-out records at Ω = {om:g} rpm, P_I = {p:g} bar "
         f"({plant} plant)")
    rec_dir = out / "records"
    op = {"omega_rpm": om, "p_inj_bar": p}
    for name, seed in (("prbs", 1), ("heldout", 2)):
        _experiment({"kind": "prbs", "name": f"demo-{name}", "operating_point": op,
                     "amplitude_v": 1.0, "seed": seed, "duration_s": dur, "lead_in_s": 0.4},
                    config, rec_dir / name)
    _experiment({"kind": "runout", "name": "demo-runout", "operating_point": op,
                 "revolutions": 40}, config, rec_dir / "runout")
    recs = {name: load_record(next((rec_dir / name).glob("*.h5")))
            for name in ("prbs", "heldout", "runout")}
    prbs, runout = recs["prbs"], recs["runout"]
    timings["records_s"] = time.perf_counter() - t0

    # 2. models: plain, diagnosed, improved; the error on the held-out record
    t0 = time.perf_counter()
    _say("[2/6] identify actuator and bearing models (PEM)")
    base = identify_record(prbs, "both", runout=runout)
    base.save(out / "G_p_plain.yaml")
    _say("[3/6] diagnose them, add what is named, compare on the held-out record")
    story = model_story(prbs, runout, recs["heldout"], base, out,
                        extra=[e.name for e in effects or []], say=_say)
    for n in story.fit_before:
        _say(f"      {n}: held-out fit {story.fit_before[n]:.2f} % -> "
             f"{story.fit_after[n]:.2f} %")
    model = story.improved
    model_path = out / "G_p.yaml"
    model.save(model_path)
    fits = {name: sm.fit_percent for name, sm in model.submodels.items()}
    timings["models_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    gbear_path = None
    rob_source = "simulated plant truth (rigd_drivers.sim.truth.plant_z): no sweep in --quick"
    if not truth:
        from rigd.ident.oprange import identify_sweep

        grid = QUICK_GRID if quick else GRID
        _say(f"      sweep {grid} and reassembled bearing model")
        _experiment({"kind": "sweep", "name": "demo-sweep", "grid": grid,
                     "at_each": {"kind": "prbs", "amplitude_v": 1.0, "seed": 1,
                                 "duration_s": 1.0 if quick else 1.5, "lead_in_s": 0.4}},
                    config, rec_dir / "sweep")
        sw = identify_sweep(rec_dir / "sweep", out / "g_bear.yaml", jobs=jobs)
        if sw.gbear is not None:
            gbear_path = out / "g_bear.yaml"
            rob_source = (f"reassembled bearing model from a {len(grid['omega_rpm'])}x"
                          f"{len(grid['p_inj_bar'])} identified grid (g_bear.yaml) x the "
                          "identified actuator")
    timings["identify_s"] = time.perf_counter() - t0

    # 3. design
    t0 = time.perf_counter()
    _say("[4/6] H∞ design on the improved model, reduction, Tustin, robustness")
    ctrl_path = out / "controller.yaml"
    plant_at = None
    if gbear_path is None:
        from rigd_drivers.sim import truth as simtruth

        plant_at = simtruth.plant_z
    design = run_design(model_path, weights, ctrl_path, range_model=gbear_path,
                        report=out / "design", plant_at=plant_at,
                        plant_at_label=rob_source).summary
    design["robustness_model"] = rob_source
    if design.get("comparison_failed"):
        _say(f"      WARNING no side-by-side with the truncated design: "
             f"{design['comparison_failed']}")
    for sub, eff in design["design_model_effects"].items():
        if eff["included"] or eff["left_out"]:
            _say(f"      {sub} design model: with {', '.join(eff['included']) or 'no effect'}"
                 + "".join(f"; {n} left out ({why})" for n, why in eff["left_out"].items()))
    for w in design.get("model_warnings", []):
        _say(f"      WARNING model {w}")
    timings["design_s"] = time.perf_counter() - t0

    # 4.+5. deploy and impacts
    t0 = time.perf_counter()
    _say("[5/6] deploy K∞ and impact tests, K∞ off and on")
    imp_dirs = []
    for pi in IMPACT_POINTS:
        for ax in ("x", "y"):
            d = out / "impacts" / f"p{pi:g}_{ax}"
            _experiment({"kind": "impact", "name": f"demo-impact-{ax}-p{pi:g}",
                         "operating_point": {"omega_rpm": 0.0, "p_inj_bar": pi}, "axis": ax,
                         "controller": [False, True], "repeats": 1 if quick else 2,
                         "pre_s": 0.01, "post_s": 0.15, "spacing_s": 0.1, "peak_n": 20.0,
                         "pulse_s": 0.001}, config, d, controller=ctrl_path)
            imp_dirs.append(d)
    timings["impacts_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    _say("[6/6] impact analysis and the story page")
    open_, closed, per = {}, {}, []
    for d in imp_dirs:
        res = analyze_impact(d, report=str(out / "impact_report" / d.name))
        for r in res["damping_increase"]:
            key = f"P{r['p_inj_bar']:g}bar_W{r['omega_rpm']:g}rpm_{r['axis']}"
            open_[key] = r["zeta_open"]
            closed[key] = r["zeta_closed"]
        per += res["summary"]
    rob = design["robustness"]
    summary = {
        "sensitivity_reduction_min": rob["sensitivity_reduction_min"],
        "sensitivity_peak_max": rob["sensitivity_peak_max"],
        "sensitivity_peak_hz": rob["sensitivity_peak_hz"],
        "sensitivity_low_increase_max": rob["sensitivity_low_increase_max"],
        "sensitivity_lowfreq_max": rob["sensitivity_lowfreq_max"],
        "sensitivity_reduction_at_resonance_min": rob["sensitivity_reduction_at_resonance_min"],
        "sensitivity_reduction_at_resonance_mode_direction_min":
            rob["sensitivity_reduction_at_resonance_mode_direction_min"],
        "disturbance_peak_reduction_min": rob["disturbance_peak_reduction_min"],
        "robustness": rob,
        "robustness_model": rob_source,
        "damping_ratio_open": open_,
        "damping_ratio_closed": closed,
        "damping_increase": {k: closed[k] / open_[k] for k in open_},
        "impacts": per,
        "gamma": design["gamma"],
        "design_method": design["method"],
        "gamma_full_order": design["gamma_full_order"],
        "gamma_full_order_optimal": design["gamma_full_order_optimal"],
        "full_order_relaxed": design["full_order_relaxed"],
        "gamma_per_model": {r["label"]: r["gamma"] for r in design["design_set"]},
        "design_comparison": design.get("comparison"),
        "design_comparison_failed": design.get("comparison_failed"),
        "design_tuning_s": design["tuning"].get("time_s"),
        "controller_order": design["controller_order"],
        "controller_order_full": design["order_full"],
        "controller_band_error": design["band_error"],
        "controller_highpass": design["highpass"],
        "controller_gain_1hz_over_band_max": design["controller_gain_1hz_over_band_max"],
        "controller_hankel_singular_values": design["hankel_singular_values"],
        "fits_percent": fits,
        "fit_percent": {name: f["validation_mean"] for name, f in fits.items()},
        "model_effects": list(dict.fromkeys(e for sm in model.submodels.values()
                                            for e in getattr(sm.structure, "effects", []))),
        "diagnosis": story.summary(),
        "design_model_effects": design["design_model_effects"],
        "design_point": {"omega_rpm": om, "p_inj_bar": p},
        "plant": plant,
        "config": str(config),
        "quick": bool(quick),
        "timings_s": timings,
    }
    write_index(out, summary, story, recs)
    timings["report_s"] = time.perf_counter() - t0
    summary["run_time_s"] = time.perf_counter() - t_start
    from rigd.fileio import atomic_write_text

    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, default=float))
    return summary


__all__ = ["run_demo"]
