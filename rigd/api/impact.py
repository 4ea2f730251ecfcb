"""analyze_impact: damping of impact responses with K∞ off and on (paper Sec. 6, Figs. 6-7)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from rigd.errors import InputError


def _records(run: Path) -> list[tuple[str, dict]]:
    """(path, manifest entry) of every impact record of a run directory or a single file."""
    if run.is_dir():
        mpath = run / "manifest.json"
        if not mpath.exists():
            raise InputError("not a run directory (no manifest.json)", str(run))
        try:
            man = json.loads(mpath.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"manifest.json is not valid JSON ({exc.msg})", str(mpath)) from None
        files = [f for f in man.get("files", []) if f.get("kind", "impact") == "impact"]
        if not files:
            raise InputError("run has no impact records", str(mpath))
        return [(str(run / f["path"]), f) for f in files]
    if not run.exists():
        raise InputError("no such file or directory", str(run))
    return [(str(run), {})]


def analyze_impact(run: str | Path, *, window_s: float = 0.08,
                   report: str | Path | None = None) -> dict[str, Any]:
    """Damping ratio ζ and frequency of every impact response of a run (paper Sec. 6).

    Each impact is fitted by a damped sinusoid (:mod:`rigd.design.impact`); per operating
    point, axis and K∞ state the mean ζ, its uncertainty (standard error over repeats combined
    with the fit's own) and the closed/open ratio are reported.

    Parameters
    ----------
    run : path
        Impact run directory of ``rigd experiment`` (``manifest.json`` lists the records with
        ``controller_on``) or one record file (HDF5 or interchange CSV).
    window_s : float
        Free-response window after the impact, s.
    report : path, optional
        Write impact figures (Figs. 6-7) into this directory.

    Returns
    -------
    dict
        ``impacts`` (one fit per record and axis: ``zeta``, ``zeta_std``, ``f_hz``...),
        ``summary`` (per Ω in rpm, P_I in bar, axis, K∞ on/off) and ``damping_increase``
        (``zeta_open``, ``zeta_closed``, ``ratio``): the ``rigd analyze-impact --json`` object.
    """
    from rigd.data import load_record
    from rigd.design.impact import analyze_record

    if not window_s > 0:
        raise InputError(f"must be > 0 (got {window_s})", "--window")
    impacts = []
    recs = []
    for path, entry in _records(Path(run)):
        rec = load_record(path)
        res = analyze_record(rec, window_s=window_s)
        on = entry.get("controller_on", res.get("controller_on"))
        om = entry.get("omega_rpm", res.get("omega_rpm"))
        p = entry.get("p_inj_bar", res.get("p_inj_bar"))
        for ax, fit in res["axes"].items():
            impacts.append({"file": Path(path).name, "omega_rpm": om, "p_inj_bar": p,
                            "controller_on": bool(on) if on is not None else None, **fit})
            recs.append((rec, fit, ax, on, om, p))
    groups: dict[tuple, list[dict]] = {}
    for imp in impacts:
        key = (imp["omega_rpm"], imp["p_inj_bar"], imp["axis"], imp["controller_on"])
        groups.setdefault(key, []).append(imp)
    summary = []
    for (om, p, ax, on), g in sorted(groups.items(), key=lambda kv: str(kv[0])):
        z = np.array([x["zeta"] for x in g])
        zs = np.array([x["zeta_std"] for x in g])
        fz = np.array([x["f_hz"] for x in g])
        sem = float(z.std(ddof=1) / np.sqrt(len(z))) if len(z) > 1 else 0.0
        summary.append({"omega_rpm": om, "p_inj_bar": p, "axis": ax, "controller_on": on,
                        "n": len(g), "zeta": float(z.mean()),
                        "zeta_std": float(np.sqrt(sem ** 2 + np.mean(zs ** 2))),
                        "f_hz": float(fz.mean())})
    ratios = []
    for s in summary:
        if s["controller_on"]:
            off = [x for x in summary if x["controller_on"] is False and x["axis"] == s["axis"]
                   and x["omega_rpm"] == s["omega_rpm"] and x["p_inj_bar"] == s["p_inj_bar"]]
            if off:
                ratios.append({"omega_rpm": s["omega_rpm"], "p_inj_bar": s["p_inj_bar"],
                               "axis": s["axis"], "zeta_open": off[0]["zeta"],
                               "zeta_closed": s["zeta"],
                               "ratio": s["zeta"] / off[0]["zeta"]})
    out = {"impacts": impacts, "summary": summary, "damping_increase": ratios}
    if report:
        from rigd.design.figures import fig_impact
        from rigd.htmlreport import Report

        rep = Report(report, "rigd analyze-impact")
        rep.table(["Ω (rpm)", "P_I (bar)", "axis", "K∞", "n", "ζ", "±", "f (Hz)"],
                  [[s["omega_rpm"], s["p_inj_bar"], s["axis"], s["controller_on"], s["n"],
                    f"{s['zeta']:.4f}", f"{s['zeta_std']:.4f}", f"{s['f_hz']:.1f}"]
                   for s in summary])
        keys = sorted({(r[4], r[5], r[2]) for r in recs}, key=str)
        for om, p, ax in keys:
            runs = []
            for rec, fit, a, on, o2, p2 in recs:
                if (o2, p2, a) == (om, p, ax) and not any(lbl == _lbl(on) for lbl, *_ in runs):
                    runs.append((_lbl(on), rec, fit))
            fig_impact(rep, f"impact_{ax}_w{om:g}_p{p:g}",
                       f"{'Horizontal' if ax == 'x' else 'Vertical'} impact at P_I = {p:g} bar, "
                       f"Ω = {om:g} rpm, K∞ off and on (Figs. 6-7)", runs, ax)
        rep.write()
        out["report"] = str(report)
    return out


def _lbl(on) -> str:
    return {True: "K∞ on", False: "K∞ off"}.get(on, "record")


__all__ = ["analyze_impact"]
