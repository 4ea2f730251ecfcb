"""``rigd identify``: grey-box actuator / bearing / generic models by the prediction-error method.

    rigd identify DATA [--runout RUNOUT] [--model auto|actuator|bearing|both|generic]
                  [-o MODEL.yaml] [--json] [--add NAME[,NAME...]] [--init MODEL.yaml]
                  [--split F | --est A:B --val A:B]
    rigd identify RUN_DIR [-o G_BEAR.yaml] [--jobs N]      # operating range of a sweep

The first 2/3 of the record are used for estimation, the last 1/3 for validation (``--split``;
or any two sample ranges, ``--est A:B --val A:B``, as ``rigd diagnose``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rigd.cli._args import (
    add_order_argument,
    add_plain_csv_arguments,
    add_range_argument,
    load_options,
    order_text,
    print_json,
    print_source,
)
from rigd.errors import InputError

HELP = "identify grey-box actuator/bearing models (PEM) from a record or a sweep run directory"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", help="record (HDF5 or interchange CSV) or a sweep run directory")
    p.add_argument("--runout", metavar="RUNOUT", help="run-out record at the same operating "
                   "point (needs phi) for the run-out filter F_r(phi)")
    p.add_argument("--model", default="auto",
                   choices=["auto", "actuator", "bearing", "both", "generic"],
                   help="sub-model(s) to identify (default: all the record's columns allow)")
    p.add_argument("-o", "--out", metavar="MODEL.yaml", help="write the model file here")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--add", metavar="NAMES", help="comma-separated effects to add to the "
                   "structure (rigd.effects.REGISTRY names)")
    p.add_argument("--init", metavar="MODEL.yaml", help="start from a previous model's "
                   "parameters (default: automatic initial guess)")
    p.add_argument("--method", choices=["auto", "pem", "oe"], default="auto",
                   help="prediction error (one-step predictor) or output error; auto "
                   "(default): prediction error for the rotor's actuator and bearing, output "
                   "error for a generic record (as rigd diagnose)")
    p.add_argument("--split", type=float, default=None,
                   help="fraction of samples for estimation; the rest validates (default 2/3)")
    p.add_argument("--est", metavar="A:B", help="estimation samples (with --val; instead of "
                   "--split, as rigd diagnose)")
    p.add_argument("--val", metavar="A:B", help="validation samples (with --est)")
    p.add_argument("--hold", choices=["auto", "zoh", "foh"], default="auto",
                   help="inputs between samples: held (zoh) or linear (foh); auto: as the "
                   "record declares (metadata 'intersample'), known for rigd recordings, "
                   "else chosen from the data by fit (docs/identify.md)")
    p.add_argument("--no-offsets", action="store_true", help="do not subtract offsets")
    p.add_argument("--no-median", action="store_true", help="no median filter on e_x, e_y")
    p.add_argument("--no-runout-filter", action="store_true",
                   help="do not apply the run-out filter even with --runout")
    p.add_argument("--jobs", type=int, default=None,
                   help="parallel processes for a run directory (default: all cores)")
    p.add_argument("--offset-samples", type=int, default=2000,
                   help="offsets = mean of the first N samples (default 2000, the paper's)")
    add_order_argument(p)
    add_range_argument(p)
    add_plain_csv_arguments(p)


def _print_human(model, out, yardstick: dict | None = None) -> None:
    split = model.split or {}
    if "fraction" in split or "validation" not in split:
        part = f"last {100 * (1 - split.get('fraction', 2 / 3)):.0f} %"
    else:
        part = "samples {}:{}".format(*split["validation"])
    for name, sm in model.submodels.items():
        fp = sm.fit_percent
        print(f"[{name}] {sm.method.upper()} fit (validation, {part}): "
              + ", ".join(f"{o} {v:.2f} %" for o, v in zip(fp["outputs"], fp["validation"]))
              + "   (estimation: " + ", ".join(f"{v:.2f} %" for v in fp["estimation"]) + ")",
              file=out)
        ys = (yardstick or {}).get(name)
        if ys is not None:
            print(f"  yardstick: {ys.describe()}", file=out)
            if ys.warning():
                print(f"  WARNING: {ys.warning()}", file=out)
        base = split.get("base")
        if base:
            print(f"  base model: {base['method_used']} fit, samples {base['window'][0]}:"
                  f"{base['window'][1]} of {base['record_samples']}, start values "
                  f"{base['start']} (rigd diagnose --method {base['method']} starts from the "
                  "same base model)", file=out)
        if "input_hold" in fp:
            print(f"  inputs between samples: {_hold_text(fp['input_hold'])}", file=out)
        for n, v, s in zip(sm.structure.names, sm.theta, sm.std):
            print(f"  {n:>16s} = {v: .6g} ± {s:.2g}", file=out)
        ro = sm.readouts
        for w in ro.get("warnings", []):
            print(f"  WARNING: {w}", file=out)
        if "order" in fp:
            print(f"  base model: {order_text(fp['order'])}", file=out)
        for m in ro.get("modes", []):
            if "f_n_hz" in m:
                print(f"  mode: f_n = {m['f_n_hz']:.2f} Hz, zeta = {m['zeta']:.4f}", file=out)
            elif "time_constant_s" in m:
                print(f"  real pole: time constant {m['time_constant_s']:.4g} s", file=out)
            elif m.get("integrator"):
                print("  integrator (pole at 0)", file=out)
        for ax, e in ro.get("axes", {}).items():
            print(f"  valve {ax}: gain {e['gain']:.4g}, f_n = {e['f_n_hz']:.1f} Hz, "
                  f"zeta = {e['zeta']:.3f}, poles {_fmt_poles(e['poles_rad_s'])} rad/s", file=out)
        if "static_gain" in ro:
            g = np.array([[np.inf if v is None else v for v in row]
                          for row in np.atleast_2d(np.array(ro["static_gain"], dtype=object))],
                         dtype=float)
            rows = "; ".join(" ".join(f"{v:.4g}" for v in row) for row in np.atleast_2d(g))
            print(f"  static gain (output per input): [{rows}]", file=out)


def _hold_text(d: dict) -> str:
    from rigd.ident.hold import HoldChoice

    return HoldChoice(d["hold"], d["source"], d.get("fits", {})).describe()


def _fmt_poles(poles) -> str:
    """Poles p of (s + p) as 'p1, p2' (real) or 're ± im j' (a complex pair)."""
    vals = [complex(p) for p in poles]
    if all(abs(v.imag) < 1e-9 for v in vals):
        return ", ".join(f"{v.real:.5g}" for v in vals)
    v = vals[0]
    return f"{v.real:.5g} ± {abs(v.imag):.5g}j"


def _prefilter_kw(args: argparse.Namespace) -> dict:
    return {"offsets": not args.no_offsets, "median": not args.no_median,
            "runout_filter": not args.no_runout_filter, "offset_samples": args.offset_samples}


def run(args: argparse.Namespace) -> int:
    from rigd import api

    if Path(args.data).is_dir():
        api.parse_effects(args.add)
        if args.est or args.val:
            raise InputError("--est/--val select samples of one record, not of a sweep run "
                             "directory (use --split)", "--est/--val")
        res = api.identify_sweep(args.data, out=args.out, jobs=args.jobs, method=args.method,
                                 split=args.split, **_prefilter_kw(args))
        if args.json:
            print_json({**res.summary(), "source": res.source})
        else:
            print_source(res.source)
            print(res.text())
        return 0
    idf = api.identify(args.data, args.model, runout=args.runout, add=args.add,
                       method=args.method, init=args.init, split=args.split, est=args.est,
                       val=args.val, hold=args.hold,
                       order=args.order, out=args.out, **_prefilter_kw(args), **load_options(args))
    if args.json:
        print_json(idf.summary())
    else:
        print_source(idf.source)
        _print_human(idf.model, sys.stdout, idf.yardstick)
        if args.out:
            print(f"model written to {args.out}")
    return 0
