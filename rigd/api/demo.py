"""run_demo: the whole story in lock-step on the simulated plant (``rigd demo``, ``make demo``).

1. records (:func:`rigd.api.run_experiment`): PRBS + run-out at the design point
   (Ω = 4000 rpm, P_I = 7 bar) and a PRBS sweep over a small (Ω, P_I) grid;
2. identification (``rigd.ident``): actuator + bearing model file G_p.yaml at the design point,
   reassembled bearing model G_bear(Ω, P_I) from the sweep;
3. design (:func:`rigd.api.design`): H∞, reduction, Tustin, robustness over 30 random operating
   points of the reassembled model cascaded with the identified actuator;
4. deploy: the controller file is loaded by the loop (validated, closed loop re-checked);
5. proof: impacts K∞ off/on at Ω = 0, P_I = 4 and 7 bar, both axes
   (:func:`rigd.api.analyze_impact`);
6. ``DIR/summary.json`` and an HTML report with every figure.
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


def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _experiment(spec: dict, config: str, run_dir: Path, controller=None) -> None:
    res = run_experiment(spec, config=config, lockstep=True, out=run_dir, controller=controller)
    if not res.ok:
        raise InputError(f"experiment {spec.get('name')} ended {res.status}: {res.message}",
                         str(run_dir))


def run_demo(out: str | Path, *, config: str = "config/sim.yaml",
             weights: str = "config/design.yaml", quick: bool = False,
             jobs: int = 2, add: list[str] | None = None) -> dict[str, Any]:
    """The whole story in lock-step on the simulated plant; returns ``summary.json``'s dict.

    Parameters
    ----------
    out : path
        Output directory (records, model files, controller, reports, ``summary.json``).
    config : path
        Simulated rig configuration.
    weights : path
        Design YAML (W_p, W_u, reduction, robustness).
    quick : bool
        Shorter records and no sweep: robustness on the ``sim`` plant's truth (for tests; only
        with a config whose fast driver is ``sim``).
    jobs : int
        Processes for the sweep fits.
    add : list of str, optional
        Catalogue effects (``rigd.effects``) added to the design-point models — the workflow's
        "add effect" step after ``diagnose``, e.g. ``["actuator_dynamics"]`` on the
        physics-grade plant (docs/plant.md).

    Returns
    -------
    dict
        ``summary.json``: γ, controller order, sensitivity figures over the operating range,
        damping ratios ζ open/closed per impact (keys ``P<bar>bar_W<rpm>rpm_<axis>``),
        identification fits (%), timings (s).
    """
    from rigd.data import load_record
    from rigd.ident.workflow import identify_record

    effects = None
    if add:
        from rigd.effects import resolve

        effects = resolve(add, "--add")   # one line naming the unknown ones, before any work
    if quick:
        from rigd.rigconfig import load_config

        fast = load_config(config).config.drivers.fast.name
        if fast != "sim":
            raise InputError(f"judges robustness on the 'sim' plant's truth, not on the "
                             f"{fast!r} plant of {config}: run without it", "--quick")
    t_start = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    timings = {}
    om, p = DESIGN_POINT
    dur = 1.5 if quick else 3.0

    # 1. records at the design point
    t0 = time.perf_counter()
    _say(f"[1/5] PRBS and run-out records at Ω = {om:g} rpm, P_I = {p:g} bar")
    rec_dir = out / "records"
    op = {"omega_rpm": om, "p_inj_bar": p}
    _experiment({"kind": "prbs", "name": "demo-prbs", "operating_point": op,
                 "amplitude_v": 1.0, "seed": 1, "duration_s": dur, "lead_in_s": 0.4},
                config, rec_dir / "prbs")
    _experiment({"kind": "runout", "name": "demo-runout", "operating_point": op,
                 "revolutions": 40}, config, rec_dir / "runout")
    prbs = load_record(next((rec_dir / "prbs").glob("*.h5")))
    runout = load_record(next((rec_dir / "runout").glob("*.h5")))
    timings["records_s"] = time.perf_counter() - t0

    # 2. identification
    t0 = time.perf_counter()
    _say("[2/5] identify actuator and bearing models (PEM)")
    model = identify_record(prbs, "both", runout=runout, effects=effects)
    model_path = out / "G_p.yaml"
    model.save(model_path)
    fits = {name: sm.fit_percent for name, sm in model.submodels.items()}
    gbear_path = None
    rob_source = "simulated plant truth (rigd_drivers.sim.truth.plant_z): no sweep in --quick"
    if not quick:
        from rigd.ident.oprange import identify_sweep

        _say(f"      sweep {GRID} and reassembled bearing model")
        _experiment({"kind": "sweep", "name": "demo-sweep", "grid": GRID,
                     "at_each": {"kind": "prbs", "amplitude_v": 1.0, "seed": 1,
                                 "duration_s": 1.5, "lead_in_s": 0.4}},
                    config, rec_dir / "sweep")
        sw = identify_sweep(rec_dir / "sweep", out / "g_bear.yaml", jobs=jobs)
        if sw.gbear is not None:
            gbear_path = out / "g_bear.yaml"
            rob_source = (f"reassembled bearing model from a {len(GRID['omega_rpm'])}x"
                          f"{len(GRID['p_inj_bar'])} identified grid (g_bear.yaml) x the "
                          "identified actuator")
    timings["identify_s"] = time.perf_counter() - t0

    # 3. design
    t0 = time.perf_counter()
    _say("[3/5] H∞ design, reduction, Tustin, robustness")
    ctrl_path = out / "controller.yaml"
    plant_at = None
    if gbear_path is None:
        from rigd_drivers.sim import truth as simtruth

        plant_at = simtruth.plant_z
    design = run_design(model_path, weights, ctrl_path, range_model=gbear_path,
                        report=out / "design", plant_at=plant_at,
                        plant_at_label=rob_source).summary
    design["robustness_model"] = rob_source
    for w in design.get("model_warnings", []):
        _say(f"      WARNING model {w}")
    timings["design_s"] = time.perf_counter() - t0

    # 4.+5. deploy and impacts
    t0 = time.perf_counter()
    _say("[4/5] deploy K∞ and impact tests, K∞ off and on")
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
    _say("[5/5] impact analysis and report")
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
        "gamma_per_model": {r["label"]: r["gamma"] for r in design["design_set"]},
        "design_comparison": design.get("comparison"),
        "design_tuning_s": design["tuning"].get("time_s"),
        "controller_order": design["controller_order"],
        "controller_order_full": design["order_full"],
        "controller_band_error": design["band_error"],
        "controller_highpass": design["highpass"],
        "controller_gain_1hz_over_band_max": design["controller_gain_1hz_over_band_max"],
        "controller_hankel_singular_values": design["hankel_singular_values"],
        "fits_percent": fits,
        "fit_percent": {name: f["validation_mean"] for name, f in fits.items()},
        "model_effects": list(add) if add else [],
        "design_point": {"omega_rpm": om, "p_inj_bar": p},
        "timings_s": timings,
    }
    _write_index(out, summary)
    timings["report_s"] = time.perf_counter() - t0
    summary["run_time_s"] = time.perf_counter() - t_start
    from rigd.fileio import atomic_write_text

    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, default=float))
    return summary


def _write_index(out: Path, s: dict) -> None:
    from rigd.htmlreport import Report

    rep = Report(out, "rigd demo: identify, design, deploy, impacts (simulated plant)")
    rep.text("Design report (Figs. 3-5): design/index.html. Impact reports (Figs. 6-7): "
             "impact_report/*/index.html. Numbers: summary.json.")
    rep.table(["quantity", "value"],
              [["gamma", f"{s['gamma']:.3f}"],
               ["controller order (full)",
                f"{s['controller_order']} ({s['controller_order_full']})"],
               ["worst in-band S_o reduction (30 realizations)",
                f"{s['sensitivity_reduction_min']:.2f}"],
               ["worst S_o reduction at each realization's own resonances (max singular "
                "value / mode direction)", f"{s['sensitivity_reduction_at_resonance_min']:.2f} / "
                f"{s['sensitivity_reduction_at_resonance_mode_direction_min']:.2f}"],
               ["peak |S_o|",
                f"{s['sensitivity_peak_max']:.2f} at {s['sensitivity_peak_hz']:.0f} Hz"],
               ["max |S_o| below 20 Hz", f"{s['sensitivity_lowfreq_max']:.3f}"],
               ["|K(1 Hz)| / max |K| in band", f"{s['controller_gain_1hz_over_band_max']:.4f}"],
               ["robustness model", s["robustness_model"]]])
    rep.table(["impact", "zeta open", "zeta closed", "ratio"],
              [[k, f"{s['damping_ratio_open'][k]:.4f}", f"{s['damping_ratio_closed'][k]:.4f}",
                f"{s['damping_increase'][k]:.2f}"] for k in s["damping_ratio_open"]])
    rep.write()


__all__ = ["run_demo"]
