"""Argument and printing helpers shared by the commands (not a command itself).

Commands never import each other; what several of them parse is defined once here.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rigd.plain import plain


def print_json(obj: Any, indent: int | None = None) -> None:
    """Print ``obj`` as strict JSON on stdout (the ``--json`` outputs): one line, or
    pretty-printed with ``indent`` spaces per level.

    Goes through :func:`rigd.plain.plain`, the project's one NaN policy: a non-finite number
    (a diverged fit is ``-inf`` %) becomes ``null``, never ``NaN``/``-Infinity``, which strict
    JSON readers (``jq``, browsers, Go, Rust) refuse; anything else JSON cannot hold is
    written as its ``str``.
    """
    sys.stdout.write(json.dumps(plain(obj), allow_nan=False, indent=indent) + "\n")


def add_range_argument(p: argparse.ArgumentParser) -> None:
    """``--range START:STOP``: use only these samples of the record."""
    p.add_argument("--range", metavar="START:STOP", help="use only samples START:STOP of the "
                   "record (Python slice, e.g. 40000: or 0:40000)")


def parse_order(text: str) -> str | int:
    """``auto`` or a number of states ≥ 1 (argparse type of ``--order``)."""
    if text == "auto":
        return text
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be 'auto' or a number of states >= 1, got "
                                         f"{text!r}")
    return v


def add_order_argument(p: argparse.ArgumentParser) -> None:
    """``--order auto|N``: states of a generic record's base model
    (rigd.ident.lti.order.choose_base)."""
    p.add_argument("--order", type=parse_order, default="auto", metavar="auto|N",
                   help="generic records: number of states of the base model (fitted exactly "
                        "or refused with the reason; a mode is 2 states), or auto (default: "
                        "family, delays and order chosen from the data — BIC on the "
                        "estimation part, held-out check; printed and in --json)")


def add_plain_csv_arguments(p: argparse.ArgumentParser) -> None:
    """``--fs/--inputs/--outputs`` for plain CSV files without rig-data metadata."""
    g = p.add_argument_group("plain CSV without rig-data metadata (e.g. Silverbox)")
    g.add_argument("--fs", help="sample rate, Hz (number or ratio, e.g. 10000000/16384)")
    g.add_argument("--inputs", help="comma-separated input columns")
    g.add_argument("--outputs", help="comma-separated output columns")
    add_mat_arguments(p)


def add_mat_arguments(p: argparse.ArgumentParser) -> None:
    """``--var/--time-column`` for MATLAB files (with ``--inputs``/``--outputs`` as 1-based
    columns and ``--fs`` when there is no time column)."""
    g = p.add_argument_group("MATLAB .mat files (v5 or v7.3): --inputs/--outputs are 1-based "
                             "columns of --var (2:4 or 2,5) or names of variables of the file")
    g.add_argument("--var", metavar="NAME", help="the matrix holding the samples, one a row "
                   "(needed when the file holds several)")
    g.add_argument("--time-column", metavar="N", help="1-based column of --var holding the "
                   "time in seconds (gives the sample rate; else give --fs)")


def load_options(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of :func:`rigd.api.load` given on the command line."""
    return {"fs": args.fs, "inputs": args.inputs, "outputs": args.outputs,
            "range": args.range, "var": args.var, "time_column": args.time_column}


def print_source(info: dict[str, Any], file: Any = None) -> None:
    """Say where the record came from (``source: simulated (drivers: fast sim)``)."""
    from rigd.api.data import source_text

    print(source_text(info), file=file)


def order_text(o: dict) -> str:
    """One line: family, states, delays and why (the ``order`` entry of the JSON)."""
    if "family" not in o:   # written before the model families
        fits = ", ".join(f"{k}: {v} %" for k, v in o["validation_fit_by_modes"].items())
        return f"{o['modes']} mode(s) (validation fit by number of modes: {fits}; {o['reason']})"
    by, what = o.get("validation_fit_by_states") or {}, "states"
    if not by and o["family"] == "mechanical":   # the mechanical base: modes of 2 states
        by, what = o.get("validation_fit_by_modes") or {}, "modes"
    fits = ", ".join(f"{k}: {v} %" for k, v in by.items())
    asked = "" if o.get("asked", "auto") == "auto" else f"--order {o['asked']}: "
    return (f"{o['family']}, {o['states']} state(s), {o['modes']} mode(s), input delays "
            f"{o['delays_samples']} samples ({asked}{o['reason']}"
            + (f"; held-out fit by number of {what}: {fits}" if fits else "") + ")")
