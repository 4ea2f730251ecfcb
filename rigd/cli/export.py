"""``rigd export``: write a record as an interchange CSV, or convert a plain CSV into one.

    rigd export REC.h5 --csv OUT.csv [--columns e_x,e_y,...] [--range START:STOP]
    rigd export --from-csv RAW.csv --fs 10000000/16384 --inputs V1 --outputs V2 -o OUT.csv
    rigd export DATA.mat --var NAME --time-column 1 --inputs 2:3 --outputs 4 -o OUT.csv
"""

from __future__ import annotations

import argparse

from rigd.cli._args import add_range_argument
from rigd.errors import InputError

HELP = ("export a recording (HDF5, CSV or MATLAB .mat) to the interchange CSV, or convert a "
        "plain CSV")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("record", nargs="?", help="recording to export (HDF5, interchange CSV, or "
                   "MATLAB .mat with --var/--inputs/--outputs/--time-column or --fs)")
    p.add_argument("--csv", metavar="OUT", help="output interchange CSV")
    p.add_argument("--columns", help="comma-separated channels to export (default: all)")
    add_range_argument(p)     # a recording's valid stretch (invalid samples are refused)
    g = p.add_argument_group("converting a plain CSV (no rig-data metadata, e.g. Silverbox)")
    g.add_argument("--from-csv", metavar="RAW", help="plain CSV: header row + numbers "
                   "(quoted names and trailing commas accepted)")
    g.add_argument("--fs", help="sample rate, Hz (a number or a ratio such as 10000000/16384)")
    g.add_argument("--inputs", help="comma-separated input (excitation) columns")
    g.add_argument("--outputs", help="comma-separated output (response) columns")
    g.add_argument("--omega-rpm", type=float, help="shaft speed, rpm (rotor data)")
    g.add_argument("--p-inj-bar", type=float, help="injection pressure, bar (rotor data)")
    g.add_argument("--kind", help="record kind (prbs, runout, impact, free)")
    m = p.add_argument_group("MATLAB .mat record (v5 or v7.3): --fs/--inputs/--outputs as "
                             "above, columns 1-based (2:4) or variable names")
    m.add_argument("--var", metavar="NAME", help="the matrix holding the samples, one a row")
    m.add_argument("--time-column", metavar="N", help="1-based time column of --var (s)")
    g.add_argument("-o", "--out", metavar="OUT", help="output interchange CSV (same as --csv)")


def _split(v: str | None) -> list[str] | None:
    return None if v is None else [s.strip() for s in v.split(",") if s.strip()]


def run(args: argparse.Namespace) -> int:
    from rigd.api.data import parse_fs, parse_range
    from rigd.data.export import convert_raw_csv, export_csv

    out = args.out or args.csv
    if args.csv and args.out and args.csv != args.out:
        raise InputError("give the output once (--csv or -o)", "arguments")
    if not out:
        raise InputError("no output file: give --csv OUT (or -o OUT)", "arguments")
    if args.from_csv:
        if args.record:
            raise InputError("give either a recording or --from-csv RAW, not both", "arguments")
        if args.fs is None:
            raise InputError("--from-csv needs --fs (the plain file does not say its sample "
                             "rate)", "arguments")
        meta = {k: v for k, v in (("omega_rpm", args.omega_rpm), ("p_inj_bar", args.p_inj_bar),
                                  ("kind", args.kind)) if v is not None}
        n = convert_raw_csv(args.from_csv, out, fs=parse_fs(args.fs), inputs=_split(args.inputs),
                            outputs=_split(args.outputs), meta=meta)
    else:
        if not args.record:
            raise InputError("no recording given (or use --from-csv RAW)", "arguments")
        from pathlib import Path

        from rigd.data.matio import is_mat

        if not Path(args.record).exists():
            raise InputError("no such file", args.record)
        mat = is_mat(args.record)
        for opt in ("fs", "inputs", "outputs", "omega_rpm", "p_inj_bar", "kind", "var",
                    "time_column"):
            if getattr(args, opt) is not None and not (
                    mat and opt in ("fs", "inputs", "outputs", "var", "time_column")):
                where = "a MATLAB .mat record or --from-csv" if opt in ("fs", "inputs",
                                                                        "outputs") else \
                    "a MATLAB .mat record" if opt in ("var", "time_column") else "--from-csv"
                raise InputError(f"--{opt.replace('_', '-')} applies only with {where}",
                                 "arguments")
        opts = None
        if mat:
            opts = {"var": args.var, "inputs": args.inputs, "outputs": args.outputs,
                    "time_column": args.time_column,
                    "fs": None if args.fs is None else parse_fs(args.fs)}
        n = export_csv(args.record, out, columns=_split(args.columns), mat=opts,
                       rng=parse_range(args.range))
    print(f"wrote {out} ({n} rows)")
    return 0
