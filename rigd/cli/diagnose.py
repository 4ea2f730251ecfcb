"""``rigd diagnose DATA``: where the model fails, which physical effect is missing, and how
much adding it helps (see docs/diagnose.md)."""

from __future__ import annotations

import argparse
import json

from rigd.errors import InputError

HELP = "diagnose a model on a record: where it fails, which physical effect is missing"


def _slice(text: str | None, what: str) -> slice | None:
    if text is None:
        return None
    try:
        a, b = text.split(":")
        s = slice(int(a) if a else None, int(b) if b else None)
    except ValueError:
        raise InputError(f"{what} must be START:STOP sample indices, got {text!r}",
                         f"--{what}") from None
    return s


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", metavar="DATA", help="record (HDF5 recording or CSV)")
    p.add_argument("--runout", metavar="RUNOUT_DATA",
                   help="run-out record at the same operating point (run-out filter, §4.4)")
    p.add_argument("--report", metavar="DIR", help="write the report page into DIR")
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
    p.add_argument("--no-refit", action="store_true",
                   help="signature tests only (fit_percent_with = base fit)")
    p.add_argument("--fs", help="sample rate of a plain CSV without metadata, Hz (number or "
                   "ratio, e.g. 10000000/16384)")
    p.add_argument("--inputs", help="input columns of a plain CSV (comma separated)")
    p.add_argument("--outputs", help="output columns of a plain CSV (comma separated)")


def run(args: argparse.Namespace) -> int:
    from rigd.diagnose.diagnosis import diagnose_record
    from rigd.effects import REGISTRY

    est, val = _slice(args.est, "est"), _slice(args.val, "val")
    if (est is None) != (val is None):
        raise InputError("give both --est and --val, or neither", "--est/--val")
    effects = None
    if args.effects:
        effects = [e.strip() for e in args.effects.split(",") if e.strip()]
        bad = [e for e in effects if e not in REGISTRY]
        if bad:
            raise InputError(f"unknown effect(s) {', '.join(bad)} (known: "
                             f"{', '.join(REGISTRY)})", "--effects")
    if args.split is not None and est is not None:
        raise InputError("give --split or --est/--val, not both", "--split")
    if args.steps < 1:
        raise InputError(f"--steps must be at least 1 (got {args.steps})", "--steps")
    from rigd.cli.identify import apply_range, load_data

    rec = apply_range(load_data(args.data, args.fs, args.inputs, args.outputs), args.range)
    ro = load_data(args.runout) if args.runout else None
    if est is not None:
        for s, what in ((est, "est"), (val, "val")):
            a, b = s.indices(rec.n)[:2]
            if b - a < 100:
                raise InputError(f"{what} range has {max(b - a, 0)} samples of {rec.n}; need "
                                 "at least 100", f"--{what}")
    diag = diagnose_record(rec, runout=ro, submodels=args.submodel, est=est, val=val,
                           effects=effects, refit=not args.no_refit, hold=args.hold,
                           split=args.split, max_steps=args.steps)
    out = diag.to_json()
    if args.report:
        from rigd.diagnose.report_page import write_report

        out["report"] = str(write_report(diag, args.report))
    if args.json:
        print(json.dumps(out))
    else:
        print(summary(out))
    return 0


def summary(out: dict) -> str:
    """Human-readable summary of the JSON result."""
    lines = [f"base model fit: {out['fit_percent']} %"]
    steps = out.get("steps", [])
    for sub, seq in (steps.items() if isinstance(steps, dict) else [("", steps)]):
        if len(seq) > 1:
            lines.append(f"error falls{' [' + sub + ']' if sub else ''}: " + " -> ".join(
                f"{'base' if s['added'] is None else '+' + s['added']} {s['fit_percent']} %"
                for s in seq))
    for f in out["findings"]:
        mark = "*" if f["significant"] else " "
        lines.append(f" {mark} {f['effect']:<18} [{f.get('submodel', '')}] score {f['score']:.2f}"
                     f"  fit with it {f['fit_percent_with']} %")
        if f["significant"]:
            lines.append(f"     {f['explanation']}")
    for c in out["cannot_reveal"]:
        lines.append(f"   cannot tell {c['effect']}: {c['why']} -> {c['experiment']}")
    for u in out["unexplained"]:
        lines.append(f"   unexplained: {u['text']}")
    if not any(f["significant"] for f in out["findings"]):
        lines.append("no catalogue effect is significant in this record"
                     + (" (see 'cannot tell' above for what it could not show)"
                        if out["cannot_reveal"] else ""))
    if "report" in out:
        lines.append(f"report: {out['report']}")
    return "\n".join(lines)
