"""``rigd design``: mixed-sensitivity H∞ controller from an identified model (paper Sec. 5).

    rigd design --model G_p.yaml --weights config/design.yaml -o config/controller.yaml
                [--range G_BEAR.yaml] [--report DIR] [--json]

The model file (``rigd identify`` output) must hold both sub-models: G_p = G_bear·G_act.
Robustness (Fig. 4) is assessed over ``robustness.n_realizations`` random operating points of
the reassembled bearing model ``--range`` (``rigd identify RUN_DIR``) cascaded with the
model's actuator; without ``--range`` only the design point is assessed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HELP = "H∞ mixed-sensitivity design, reduction, Tustin; writes the controller YAML"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", required=True, metavar="G_p.yaml",
                   help="identified model file with actuator and bearing sub-models")
    p.add_argument("--weights", default="config/design.yaml", metavar="DESIGN.yaml",
                   help="design weights and options (default config/design.yaml)")
    p.add_argument("-o", "--out", required=True, metavar="CONTROLLER.yaml",
                   help="controller file to write (atomically)")
    p.add_argument("--range", metavar="G_BEAR.yaml", dest="range_model",
                   help="reassembled bearing model over (Ω, P_I) for the robustness check")
    p.add_argument("--report", metavar="DIR", help="write figures (weights, S_o, K(z)) here")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run_design(model_path, weights_path, out, *, range_model=None, report=None,
               plant_at=None, plant_at_label: str = "") -> dict:
    """Design, check and write; returns the summary dict (also used by ``rigd demo``).

    ``plant_at(omega_rpm, p_inj_bar) -> G_p`` may replace ``range_model`` as the operating-range
    model of the robustness check (``rigd demo --quick`` uses the simulated plant's truth).
    """
    from rigd.design import pipeline, robustness
    from rigd.design.weights import load_design_config
    from rigd.errors import InputError
    from rigd.ident.modelfile import load_model, sha256_file

    cfg = load_design_config(weights_path)
    model = load_model(model_path)
    G = model.plant()
    res = pipeline.design_controller(G, cfg)
    pipeline.save_design(out, res, cfg, model_hash=sha256_file(model_path), design_model=G,
                         note=f"designed on {Path(model_path).name} at "
                              f"{model.operating_point or 'unknown operating point'}")
    summary = {"controller": str(out), "model": str(model_path), **res.summary()}
    rob = None
    if range_model:
        from rigd.ident.oprange import ReassembledBearing

        gb = ReassembledBearing.load(range_model)
        Gact = model.ss("actuator")
        rob = robustness.analyze(lambda om, p: gb.at(om, p) * Gact, res.K_z, cfg.robustness)
        summary["robustness"] = rob.summary()
        summary["robustness_model"] = f"reassembled {range_model} x actuator of {model_path}"
    elif plant_at is not None:
        rob = robustness.analyze(plant_at, res.K_z, cfg.robustness)
        summary["robustness"] = rob.summary()
        summary["robustness_model"] = plant_at_label
    else:
        r, sig = robustness.assess(G, res.K_z, robustness.default_freqs(cfg.fs_hz),
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
    return summary


def run(args: argparse.Namespace) -> int:
    s = run_design(args.model, args.weights, args.out, range_model=args.range_model,
                   report=args.report)
    if args.json:
        json.dump(s, sys.stdout, default=float)
        sys.stdout.write("\n")
    else:
        print(f"controller written: {s['controller']} (order {s['controller_order']} of "
              f"{s['order_full']}, gamma = {s['gamma']:.3f})")
        if "robustness" in s:
            r = s["robustness"]
            print(f"robustness over {r['n_realizations']} operating points: stable="
                  f"{r['all_stable']}, in-band reduction >= {r['sensitivity_reduction_min']:.2f}"
                  f", peak |S_o| = {r['sensitivity_peak_max']:.2f} at "
                  f"{r['sensitivity_peak_hz']:.0f} Hz")
    return 0
