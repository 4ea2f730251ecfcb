"""``rigd compare MODEL DATA``: fit per output, residual statistics, HTML report.

The whole DATA record is simulated (give held-out data, or ``--part validation`` to use the
validation part of the identification record as stored in the model file). The work is
:func:`rigd.api.compare`.
"""

from __future__ import annotations

import argparse

from rigd.cli._args import (
    add_plain_csv_arguments,
    add_range_argument,
    load_options,
    print_json,
    print_source,
)

HELP = "compare an identified model with a measured record (fit, residuals, report)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="model file written by rigd identify")
    p.add_argument("data", help="record (HDF5 recording, CSV or MATLAB .mat)")
    p.add_argument("--runout", metavar="RUNOUT", help="run-out record for the run-out filter")
    p.add_argument("--part", choices=["all", "validation", "estimation"], default="all",
                   help="which part of the record (the model file's split) to compare")
    p.add_argument("--x0", choices=["estimation", "estimate"], default="estimation",
                   help="--part validation: initial state and output offsets from the "
                        "estimation part (default; nothing is fitted on the held-out samples) "
                        "or re-estimated on the validation samples themselves (estimate)")
    p.add_argument("--report", metavar="DIR", help="write the report into DIR: index.html "
                   "(interactive, self-contained, opens offline) and the PNG figures")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    add_range_argument(p)
    add_plain_csv_arguments(p)


def run(args: argparse.Namespace) -> int:
    from rigd import api
    from rigd.ident.compare import X0_LABELS

    res = api.compare(args.model, args.data, runout=args.runout, part=args.part, x0=args.x0,
                      report=args.report, title=f"{args.model} vs {args.data}",
                      **load_options(args))
    out = res.summary()
    if args.json:
        print_json(out)
    else:
        print_source(res.source)
        for name, c in res.comparisons.items():
            print(f"[{name}] initial state "
                  f"{X0_LABELS[c.extra.get('initial_state', 'estimate')]}")
            print(f"[{name}] " + ", ".join(f"{o}: fit {f:.2f} %, residual rms "
                                          f"{c.residual[o]['rms']:.4g}"
                                          for o, f in zip(c.data.output_names, c.fit)))
        for name, ys in res.yardstick.items():
            if ys is not None:
                print(f"[{name}] yardstick: {ys.describe()}")
        for w in res.warnings:
            print(f"WARNING {w}")
        if args.report:
            print(f"report: {out['report']}")
    return 0
