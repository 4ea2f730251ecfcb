"""``rigd design``: mixed-sensitivity H∞ controller from an identified model (paper Sec. 5).

    rigd design --model G_p.yaml --weights config/design.yaml -o config/controller.yaml
                [--range G_BEAR.yaml] [--report DIR] [--json]

The model file (``rigd identify`` output) must hold both sub-models: G_p = G_bear·G_act.
Robustness (Fig. 4) is assessed over ``robustness.n_realizations`` random operating points of
the reassembled bearing model ``--range`` (``rigd identify RUN_DIR``) cascaded with the
model's actuator; without ``--range`` only the design point is assessed. The work is
:func:`rigd.api.design`.
"""

from __future__ import annotations

import argparse

from rigd.cli._args import print_json

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
    p.add_argument("--method", choices=("structured", "truncate"),
                   help="structured: fixed-order multi-model H∞ tuning (default of "
                        "config/design.yaml); truncate: balanced truncation of the full order")
    p.add_argument("--order", type=int, metavar="N",
                   help="controller states (default reduction.order of the design YAML)")
    p.add_argument("--allow-flagged", action="store_true",
                   help="design even on a model with an unstable mode (refused by default; "
                        "a parameter at a bound is only warned about)")


def run(args: argparse.Namespace) -> int:
    from rigd.api.design import design

    s = design(args.model, args.weights, args.out, range_model=args.range_model,
               report=args.report, method=args.method, order=args.order,
               allow_flagged=args.allow_flagged).summary
    if args.json:
        print_json(s)
    else:
        print(f"controller written: {s['controller']} ({s['method']}, order "
              f"{s['controller_order']}; full order {s['order_full']}, gamma = {s['gamma']:.3f})")
        for w in s.get("model_warnings", []):
            print(f"WARNING model {w}")
        if s.get("comparison_failed"):
            print(f"WARNING no side-by-side with the truncated design: "
                  f"{s['comparison_failed']}")
        if "robustness" in s:
            r = s["robustness"]
            print(f"robustness over {r['n_realizations']} operating points: stable="
                  f"{r['all_stable']}, in-band reduction >= {r['sensitivity_reduction_min']:.2f}"
                  f", peak |S_o| = {r['sensitivity_peak_max']:.2f} at "
                  f"{r['sensitivity_peak_hz']:.0f} Hz")
    return 0
