"""``rigd analyze-impact``: damping ratio and frequency of impact responses (paper Sec. 6).

    rigd analyze-impact RUN [--json] [--report DIR] [--window S]

RUN is an impact run directory of ``rigd experiment`` (its ``manifest.json`` lists the records
with ``controller_on``) or one record file (HDF5 or interchange CSV); the analysis is
:func:`rigd.api.analyze_impact`.
"""

from __future__ import annotations

import argparse

from rigd.cli._args import print_json

HELP = "damping ratio and frequency of impact responses (K∞ off/on) with uncertainty"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", help="impact run directory (manifest.json) or a record file")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--report", metavar="DIR", help="write impact figures (Figs. 6-7) here")
    p.add_argument("--window", type=float, default=0.08, metavar="S",
                   help="free-response window after the impact, s (default 0.08)")


def run(args: argparse.Namespace) -> int:
    from rigd.api.impact import analyze_impact

    out = analyze_impact(args.run, window_s=args.window, report=args.report)
    if args.json:
        print_json(out)
        return 0
    for s in out["summary"]:
        k = {True: "on ", False: "off", None: "?  "}[s["controller_on"]]
        print(f"Ω={s['omega_rpm']:g} rpm P_I={s['p_inj_bar']:g} bar axis {s['axis']} K∞ {k}: "
              f"ζ = {s['zeta']:.4f} ± {s['zeta_std']:.4f}, f = {s['f_hz']:.1f} Hz (n={s['n']})")
    for r in out["damping_increase"]:
        print(f"damping increase at P_I={r['p_inj_bar']:g} bar axis {r['axis']}: "
              f"{r['zeta_open']:.4f} -> {r['zeta_closed']:.4f} (x{r['ratio']:.2f})")
    return 0
