"""``rigd demo --out DIR``: the whole story in lock-step on the simulated plant (``make demo``).

The pipeline is :func:`rigd.api.demo.run_demo`:

1. records (``rigd experiment`` runner): PRBS + run-out at the design point
   (Ω = 4000 rpm, P_I = 7 bar) and a PRBS sweep over a small (Ω, P_I) grid;
2. identification (``rigd.ident``): actuator + bearing model file G_p.yaml at the design point,
   reassembled bearing model G_bear(Ω, P_I) from the sweep;
3. design (``rigd design``): H∞, reduction, Tustin, robustness over 30 random operating points
   of the reassembled model cascaded with the identified actuator;
4. deploy: the controller file is loaded by the loop (validated, closed loop re-checked);
5. proof: impacts K∞ off/on at Ω = 0, P_I = 4 and 7 bar, both axes (``rigd analyze-impact``);
6. ``DIR/summary.json`` and an HTML report with every figure.
"""

from __future__ import annotations

import argparse
import json

HELP = "run the whole story (identify, design, deploy, impacts) on the simulated plant"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo-out", help="output directory (default demo-out)")
    p.add_argument("--config", default="config/sim.yaml", help="sim config (default "
                   "config/sim.yaml)")
    p.add_argument("--weights", default="config/design.yaml", help="design weights")
    p.add_argument("--quick", action="store_true",
                   help="shorter records, no sweep (robustness on the sim plant's "
                        "truth: sim configs only); for tests")
    p.add_argument("--jobs", type=int, default=2, help="processes for the sweep fits")
    p.add_argument("--add", default="", metavar="NAME[,NAME...]",
                   help="catalogue effects added to the design-point models (after diagnose), "
                        "e.g. actuator_dynamics on config/sim_reynolds.yaml")


def run(args: argparse.Namespace) -> int:
    from rigd.api.demo import run_demo

    add = [e.strip() for e in args.add.split(",") if e.strip()]
    s = run_demo(args.out, config=args.config, weights=args.weights, quick=args.quick,
                 jobs=args.jobs, add=add)
    print(json.dumps({k: s[k] for k in ("sensitivity_reduction_min",
                                        "sensitivity_reduction_at_resonance_min",
                                        "sensitivity_lowfreq_max", "sensitivity_peak_max",
                                        "damping_ratio_open", "damping_ratio_closed",
                                        "damping_increase", "gamma", "controller_order",
                                        "fit_percent", "run_time_s")}, indent=2, default=float))
    return 0
