"""``rigd diagnose DATA``: where the model fails, which physical effect is missing, and how
much adding it helps (see docs/diagnose.md); the work is :func:`rigd.api.diagnose`."""

from __future__ import annotations

import argparse

from rigd.api.data import source_text
from rigd.cli._args import (
    add_mat_arguments,
    add_order_argument,
    load_options,
    order_text,
    print_json,
)

HELP = "diagnose a model on a record: where it fails, which physical effect is missing"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", metavar="DATA", help="record (HDF5 recording, CSV or MATLAB .mat)")
    p.add_argument("--runout", metavar="RUNOUT_DATA",
                   help="run-out record at the same operating point (run-out filter, §4.4)")
    p.add_argument("--report", metavar="DIR", help="write the report into DIR: index.html "
                   "(interactive: switch each tested effect on/off; self-contained, opens "
                   "offline) and the PNG figures")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--submodel", choices=["actuator", "bearing", "generic"], action="append",
                   help="sub-model(s) to examine (default: all the record supports)")
    p.add_argument("--est", metavar="A:B", help="estimation samples (default: --split)")
    p.add_argument("--val", metavar="A:B", help="validation samples (default: --split)")
    p.add_argument("--split", type=float, default=None,
                   help="fraction of samples for estimation, the rest validates (default 2/3, "
                        "as rigd identify)")
    p.add_argument("--range", metavar="START:STOP", help="use only samples START:STOP of the "
                   "record (as rigd identify --range)")
    p.add_argument("--steps", type=int, default=3,
                   help="most effects added one after the other (forward selection, default 3)")
    p.add_argument("--effects", metavar="NAME[,NAME...]", help="only test these effects")
    p.add_argument("--hold", choices=["auto", "zoh", "foh"], default="auto",
                   help="inputs between samples: held (zoh) or linear (foh); auto, as rigd "
                        "identify: declared by the record, known for rigd recordings, else "
                        "chosen from the data by fit")
    add_order_argument(p)
    p.add_argument("--method", choices=["oe", "pem"], default="oe",
                   help="fit method of the base model and every refit: output error "
                        "(default; rigd identify --method oe fits the same base model) or "
                        "prediction error")
    p.add_argument("--init", metavar="MODEL.yaml", help="start the base fit from a previous "
                   "model's parameters (as rigd identify --init)")
    p.add_argument("--model", metavar="MODEL.yaml",
                   help="diagnose this model (rigd identify -o or --save-model) on DATA: "
                        "not refitted; what it misses here and what moves when its "
                        "structure is refitted here, in words")
    p.add_argument("--save-model", metavar="MODEL.yaml",
                   help="write the model the diagnosis ends with (base + the effects it "
                        "added, as fitted) as a model file for compare, design and --init")
    p.add_argument("--no-refit", action="store_true",
                   help="signature tests only, no effect is refitted (fit_percent_with = "
                        "base fit); with --model the given model's structure is still "
                        "refitted once, to say what moved")
    p.add_argument("--fs", help="sample rate of a plain CSV without metadata, Hz (number or "
                   "ratio, e.g. 10000000/16384)")
    p.add_argument("--inputs", help="input columns of a plain CSV (comma separated)")
    p.add_argument("--outputs", help="output columns of a plain CSV (comma separated)")
    add_mat_arguments(p)


def run(args: argparse.Namespace) -> int:
    from rigd import api

    res = api.diagnose(args.data, runout=args.runout, submodels=args.submodel, est=args.est,
                       val=args.val, split=args.split, effects=args.effects,
                       refit=not args.no_refit, hold=args.hold, steps=args.steps,
                       order=args.order, method=args.method, init=args.init,
                       save_model=args.save_model, model=args.model, report=args.report,
                       **load_options(args))
    out = res.summary()
    if args.json:
        print_json(out)
    else:
        print(summary(out))
    return 0


def summary(out: dict) -> str:
    """Human-readable summary of the JSON result."""
    from rigd.ident.figures import REFIT_FLAGS

    lines = [source_text(out.get("source") or {}), f"base model fit: {out['fit_percent']} %"]
    for sub, b in (out.get("base") or {}).items():
        if sub in (out.get("given_model") or {}):
            continue    # the given model's line below says what the base is
        lines.append(f"base model [{sub}]: {b['method_used']} fit, samples "
                     f"{b['window'][0]}:{b['window'][1]} of {b['record_samples']}, hold "
                     f"{b['hold']}, start values {b['start']}")
    for sub, g in (out.get("given_model") or {}).items():
        lines.append(f"given model [{sub}]: {g['text']}")
    for sub, o in (out.get("order") or {}).items():
        lines.append(f"base model [{sub}]: {order_text(o)}")
    for sub, y in (out.get("yardstick") or {}).items():
        lines.append(f"yardstick [{sub}]: {y['text']}")
    lines += [f"   WARNING {n}" for n in out.get("notes", []) if "WARNING" in n]
    steps = out.get("steps", [])
    for sub, seq in (steps.items() if isinstance(steps, dict) else [("", steps)]):
        if len(seq) > 1:
            lines.append(f"error falls{' [' + sub + ']' if sub else ''}: " + " -> ".join(
                f"{'base' if s['added'] is None else '+' + s['added']} {s['fit_percent']} %"
                for s in seq))
    for f in out["findings"]:
        mark = "*" if f["significant"] else " "
        site = f" ({f['site']})" if f.get("site") else ""
        fw = f["fit_percent_with"]
        flag = f.get("refit_flag")
        with_it = ("not refitted" if fw is None and flag is None else
                   f"fit with it {'-' if fw is None else fw} %")
        if flag is not None:  # rigd.ident.figures.refit_flag: listed, never ranked
            with_it += f" (refit {REFIT_FLAGS.get(flag, flag)}: not ranked)"
        lines.append(f" {mark} {f['effect'] + site:<18} [{f.get('submodel', '')}] score "
                     f"{f['score']:.2f}  {with_it}")
        if f["significant"]:
            lines.append(f"     {f['explanation']}")
    for c in out["cannot_reveal"]:
        lines.append(f"   cannot tell {c['effect']}: {c['why']} -> {c['experiment']}")
    # effects the base could not carry, and those fitted on a window of a long record: said
    # here too, not only on the report page (rigd.diagnose.selection's notes)
    lines += [f"   not tried: {n}" for n in out.get("notes", []) if " not offered: " in n]
    lines += [f"   note: {n}" for n in out.get("notes", []) if " fitted on the first " in n]
    for u in out["unexplained"]:
        lines.append(f"   unexplained: {u['text']}")
    if not any(f["significant"] for f in out["findings"]):
        lines.append("no catalogue effect is significant in this record"
                     + (" (see 'cannot tell' above for what it could not show)"
                        if out["cannot_reveal"] else ""))
    if "saved_model" in out:
        lines.append(f"model saved: {out['saved_model']} (rigd compare MODEL DATA to check it "
                     "on another record)")
    if "report" in out:
        lines.append(f"report: {out['report']}")
    return "\n".join(lines)
