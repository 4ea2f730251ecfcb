"""``rigd demo --out DIR``: the whole story in lock-step on the simulated rig (``make demo``).

The pipeline is :func:`rigd.api.demo.run_demo` (default plant: the physics-grade
``config/sim_reynolds.yaml``, whose structure is not the grey-box model class):

1. records (``rigd experiment`` runner): PRBS, held-out PRBS and run-out at the design point
   (Ω = 4000 rpm, P_I = 7 bar) and a PRBS sweep over a small (Ω, P_I) grid;
2. models: plain actuator + bearing models, ``rigd diagnose`` of the identification record,
   each sub-model refitted with the effects it names (``identify --add``), both compared on
   the held-out record; reassembled bearing model G_bear(Ω, P_I) from the sweep;
3. design (``rigd design``) on the improved model: H∞, reduction, Tustin, robustness over 30
   random operating points of the reassembled model cascaded with the identified actuator;
4. deploy: the controller file is loaded by the loop (validated, closed loop re-checked);
5. proof: impacts K∞ off/on at Ω = 0, P_I = 4 and 7 bar, both axes (``rigd analyze-impact``);
6. ``DIR/summary.json`` and ``DIR/index.html``, the story with every figure.
"""

from __future__ import annotations

import argparse

from rigd.cli._args import print_json

HELP = ("run the whole story (identify, diagnose, add, design, deploy, impacts) on the "
        "simulated rig")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo-out", help="output directory (default demo-out)")
    p.add_argument("--config", default="config/sim_reynolds.yaml",
                   help="simulated rig config (default config/sim_reynolds.yaml, the "
                        "physics-grade plant; config/sim.yaml: the paper's model class)")
    p.add_argument("--weights", default="config/design.yaml", help="design weights")
    p.add_argument("--quick", action="store_true",
                   help="for tests: the same steps with shorter records, a 2 x 2 sweep "
                        "(none on the sim plant: its truth) and one impact per state")
    p.add_argument("--jobs", type=int, default=2, help="processes for the sweep fits")
    p.add_argument("--add", default="", metavar="NAME[,NAME...]",
                   help="catalogue effects added to the design-point models beside the ones "
                        "diagnose names")


def run(args: argparse.Namespace) -> int:
    from rigd.api.demo import run_demo

    add = [e.strip() for e in args.add.split(",") if e.strip()]
    s = run_demo(args.out, config=args.config, weights=args.weights, quick=args.quick,
                 jobs=args.jobs, add=add)
    keys = ("sensitivity_reduction_min", "sensitivity_reduction_at_resonance_min",
            "sensitivity_lowfreq_max", "sensitivity_peak_max", "damping_ratio_open",
            "damping_ratio_closed", "damping_increase", "gamma", "controller_order",
            "fit_percent", "run_time_s")
    shown = {k: s[k] for k in keys}
    shown["diagnosis"] = {k: s["diagnosis"][k] for k in ("named", "named_by_submodel",
                                                         "fit_before", "fit_after")}
    print_json(shown, indent=2)
    return 0
