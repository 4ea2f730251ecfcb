"""``rigd compare MODEL DATA``: fit per output, residual statistics, HTML report.

The whole DATA record is simulated (give held-out data, or ``--part validation`` to use the
validation part of the identification record as stored in the model file).
"""

from __future__ import annotations

import argparse
import json
import sys

HELP = "compare an identified model with a measured record (fit, residuals, report)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="model file written by rigd identify")
    p.add_argument("data", help="record (HDF5 or interchange CSV)")
    p.add_argument("--runout", metavar="RUNOUT", help="run-out record for the run-out filter")
    p.add_argument("--part", choices=["all", "validation", "estimation"], default="all",
                   help="which part of the record (the model file's split) to compare")
    p.add_argument("--report", metavar="DIR", help="write an HTML report into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    from rigd.cli.identify import add_range_argument

    add_range_argument(p)
    g = p.add_argument_group("plain CSV without rig-data metadata (e.g. Silverbox)")
    g.add_argument("--fs", help="sample rate, Hz (number or ratio)")
    g.add_argument("--inputs", help="comma-separated input columns")
    g.add_argument("--outputs", help="comma-separated output columns")


def run(args: argparse.Namespace) -> int:
    from rigd.cli.identify import apply_range, load_data
    from rigd.ident.compare import compare_model, summary, write_report
    from rigd.ident.modelfile import load_model

    model = load_model(args.model)
    record = apply_range(load_data(args.data, args.fs, args.inputs, args.outputs), args.range)
    runout = load_data(args.runout) if args.runout else None
    comps = compare_model(model, record, runout, args.part)
    res = summary(comps)
    if args.report:
        res["report"] = str(write_report(comps, args.report, f"{args.model} vs {args.data}"))
    if args.json:
        json.dump(res, sys.stdout)
        print()
    else:
        for name, c in comps.items():
            print(f"[{name}] " + ", ".join(f"{o}: fit {f:.2f} %, residual rms "
                                          f"{c.residual[o]['rms']:.4g}"
                                          for o, f in zip(c.data.output_names, c.fit)))
        if args.report:
            print(f"report: {res['report']}")
    return 0
