"""``rigd identify``: grey-box actuator / bearing / generic models by the prediction-error method.

    rigd identify DATA [--runout RUNOUT] [--model auto|actuator|bearing|both|generic]
                  [-o MODEL.yaml] [--json] [--add NAME[,NAME...]] [--init MODEL.yaml]
    rigd identify RUN_DIR [-o G_BEAR.yaml] [--jobs N]      # operating range of a sweep

The first 2/3 of the record are used for estimation, the last 1/3 for validation (``--split``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

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
    p.add_argument("--method", choices=["pem", "oe"], default="pem",
                   help="prediction error (one-step predictor, default) or output error")
    p.add_argument("--split", type=float, default=2.0 / 3.0,
                   help="fraction of samples for estimation; the rest validates (default 2/3)")
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
    add_range_argument(p)
    g = p.add_argument_group("plain CSV without rig-data metadata (e.g. Silverbox)")
    g.add_argument("--fs", help="sample rate, Hz (number or ratio, e.g. 10000000/16384)")
    g.add_argument("--inputs", help="comma-separated input columns")
    g.add_argument("--outputs", help="comma-separated output columns")


def add_range_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--range", metavar="START:STOP", help="use only samples START:STOP of the "
                   "record (Python slice, e.g. 40000: or 0:40000)")


def apply_range(record, text: str | None):
    """``record`` sliced by ``START:STOP`` (InputError on a malformed or empty range)."""
    if not text:
        return record
    try:
        a, b = text.split(":")
        start = int(a) if a.strip() else None
        stop = int(b) if b.strip() else None
    except ValueError:
        raise InputError(f"--range must look like START:STOP, got {text!r}", "--range") from None
    out = record.slice(start, stop)
    if out.n == 0:
        raise InputError(f"--range {text} selects no samples of {record.n}", "--range")
    return out


def load_data(path: str, fs: str | None = None, inputs: str | None = None,
              outputs: str | None = None):
    """Load a record through ``rigd.data.io.load_record`` (plain CSV if ``fs`` is given)."""
    from rigd.data.io import load_record

    if fs is None:
        if inputs or outputs:
            raise InputError("--inputs/--outputs are for plain CSV files and need --fs")
        return load_record(path)
    from rigd.cli.export import parse_fs

    def split(v):
        return [c.strip() for c in v.split(",") if c.strip()] if v else None

    return load_record(path, fs=parse_fs(fs), inputs=split(inputs), outputs=split(outputs))


def parse_effects(text: str | None) -> list[str]:
    """Effect names from ``--add``; unknown names -> InputError listing the known ones."""
    if not text:
        return []
    names = [n.strip() for n in text.split(",") if n.strip()]
    try:
        from rigd.effects import REGISTRY
    except ImportError:  # pragma: no cover
        REGISTRY = {}
    unknown = [n for n in names if n not in REGISTRY]
    if unknown:
        raise InputError(f"unknown effect(s) {', '.join(unknown)} (known: "
                         f"{', '.join(sorted(REGISTRY)) or 'none'})", "--add")
    return names


def prefilter_options(args):
    from rigd.ident.prefilter import PrefilterOptions

    if args.offset_samples <= 0:
        raise InputError("--offset-samples must be positive", "--offset-samples")
    return PrefilterOptions(offsets=not args.no_offsets, median=not args.no_median,
                            runout=not args.no_runout_filter,
                            offset_samples=args.offset_samples)


def summary_json(model, effects: list[str]) -> dict:
    """The ``--json`` object of ../shared/DESIGN.md for a model file."""
    subs = model.submodels
    if len(subs) == 1:
        (name, sm), = subs.items()
        fp = sm.fit_percent["validation_mean"]
        params = sm.parameters
        std = {n: float(s) for n, s in zip(sm.structure.names, sm.std)}
        ro = sm.readouts
    else:
        fp = {n: sm.fit_percent["validation_mean"] for n, sm in subs.items()}
        params = {n: sm.parameters for n, sm in subs.items()}
        std = {n: {p: float(s) for p, s in zip(sm.structure.names, sm.std)}
               for n, sm in subs.items()}
        ro = {n: sm.readouts for n, sm in subs.items()}
    from rigd.ident.modelfile import _plain

    return {"fit_percent": fp, "parameters": params, "effects": effects,
            "std": std, "readouts": _plain(ro),
            "fit_percent_per_output": {n: sm.fit_percent for n, sm in subs.items()},
            "split": model.split, "operating_point": model.operating_point}


def _print_human(model, out) -> None:
    for name, sm in model.submodels.items():
        fp = sm.fit_percent
        print(f"[{name}] {sm.method.upper()} fit (validation, last "
              f"{100 * (1 - model.split.get('fraction', 2 / 3)):.0f} %): "
              + ", ".join(f"{o} {v:.2f} %" for o, v in zip(fp["outputs"], fp["validation"]))
              + "   (estimation: " + ", ".join(f"{v:.2f} %" for v in fp["estimation"]) + ")",
              file=out)
        if "input_hold" in fp:
            print(f"  inputs between samples: {_hold_text(fp['input_hold'])}", file=out)
        for n, v, s in zip(sm.structure.names, sm.theta, sm.std):
            print(f"  {n:>16s} = {v: .6g} ± {s:.2g}", file=out)
        ro = sm.readouts
        for m in ro.get("modes", []):
            if "f_n_hz" in m:
                print(f"  mode: f_n = {m['f_n_hz']:.2f} Hz, zeta = {m['zeta']:.4f}", file=out)
        for ax, e in ro.get("axes", {}).items():
            print(f"  valve {ax}: gain {e['gain']:.4g}, f_n = {e['f_n_hz']:.1f} Hz, "
                  f"zeta = {e['zeta']:.3f}, poles {_fmt_poles(e['poles_rad_s'])} rad/s", file=out)
        if "static_gain" in ro:
            g = np.asarray(ro["static_gain"], dtype=float)
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


def run(args: argparse.Namespace) -> int:
    from rigd.ident.modelfile import load_model, sha256_file

    effects = parse_effects(args.add)
    if Path(args.data).is_dir():
        from rigd.ident.oprange import identify_sweep

        res = identify_sweep(args.data, out=args.out, jobs=args.jobs, method=args.method,
                             options=prefilter_options(args), split=args.split)
        if args.json:
            json.dump(res.summary(), sys.stdout)
            print()
        else:
            print(res.text())
        return 0
    from rigd.ident.workflow import identify_record

    record = apply_range(load_data(args.data, args.fs, args.inputs, args.outputs), args.range)
    runout = load_data(args.runout) if args.runout else None
    init = load_model(args.init) if args.init else None
    model = identify_record(record, args.model, runout=runout, options=prefilter_options(args),
                            method=args.method, init=init, effects=effects, split=args.split,
                            data_hash=sha256_file(args.data), hold=args.hold)
    if args.out:
        model.save(args.out)
    if args.json:
        json.dump(summary_json(model, effects), sys.stdout)
        print()
    else:
        _print_human(model, sys.stdout)
        if args.out:
            print(f"model written to {args.out}")
    return 0
