"""``demo-out/index.html``: the demo as a story a newcomer reads first.

Records → the plain model against measurement → the diagnosis and the error falling on a
held-out record → the H∞ design (paper Figs. 3–5) → impacts K∞ off/on (Figs. 6–7). Every
figure is shown inline: drawn here (records, held-out residuals) or the PNG that the step's
own report wrote (compare, diagnose, design, sweep, analyze-impact), linked to that report;
every link is relative to the page, so the folder can be moved, opened from ``file://`` or
served by ``rigd web``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rigd.htmlreport import Report

ZOOM_S = 0.08   # the excerpt shown of a record (s): a few periods of the 100-130 Hz modes


def _rel(out: Path, p: Path) -> str:
    return p.relative_to(out).as_posix()


def _excerpt(n: int, fs: float) -> slice:
    k0 = n // 2
    return slice(k0, min(n, k0 + int(ZOOM_S * fs)))


def _records(rep: Report, out: Path, s: dict, recs: dict[str, Any]) -> None:
    op = s["design_point"]
    rep.heading("1. Records at the design point")
    rep.text(f"The loop runs the plant in lock-step at Ω = {op['omega_rpm']:g} rpm, "
             f"P_I = {op['p_inj_bar']:g} bar (the paper's design point) and records at 5 kHz: "
             "a ±1 V PRBS on the lumped references r (identification), a second PRBS of "
             "another seed (held out: no fit ever sees it) and a run-out record (the shaft "
             "turning, no excitation; it feeds the run-out filter).")
    rec = recs["prbs"]
    c = rec.columns
    sl = _excerpt(rec.n, rec.fs)
    t = c["t"][sl] - c["t"][sl][0]
    fig, ax = rep.figure("records", "The identification PRBS (an excerpt): reference r, "
                         "valve position u and journal displacement e, both axes",
                         nrows=3, sharex=True)
    for k, (col, unit) in enumerate((("r", "V"), ("u", "V"), ("e", "µm"))):
        for axis in "xy":
            ax[k].plot(t, c[f"{col}_{axis}"][sl], lw=0.8, label=f"{col}_{axis}")
        ax[k].set_ylabel(f"{col} ({unit})")
        ax[k].legend(loc="upper right", fontsize=7)
        ax[k].grid(True, alpha=0.3)
    ax[-1].set_xlabel("time (s)")
    rep.links([(_rel(out, p), p.parent.name + "/" + p.name)
               for p in sorted((out / "records").glob("*/*.h5"))], "Records (HDF5): ")


def _plain_model(rep: Report, out: Path, st) -> None:
    rep.heading("2. The plain models against measurement")
    rep.text("Identified by the prediction-error method on the identification PRBS: the "
             "actuator (valve references r → valve positions u, Eq. 8) and the bearing "
             "(valve positions u → displacement e, Eq. 4, the paper's grey-box structure). "
             "Simulated from the inputs alone on the held-out record:")
    rep.table(["sub-model", "fit on the held-out record (%)", "error (100 − fit)"],
              [[n, f"{f:.2f}", f"{100 - f:.2f}"] for n, f in st.fit_before.items()])
    png = out / "compare_before" / "bearing_time_zoom.png"
    if png.exists():
        rep.image(_rel(out, png), "The plain bearing model on the held-out record (zoom): "
                  "measured and simulated e, the inputs u, the residual. Click for the "
                  "interactive comparison.", href="compare_before/index.html")
    rep.links([("compare_before/index.html", "interactive comparison"),
               ("compare_before/figures.html", "all its figures"),
               ("G_p_plain.yaml", "the plain model file")], "Plain models: ")


def _diagnosis(rep: Report, out: Path, st) -> None:
    d = st.summary()
    rep.heading("3. Diagnosis: which physical effect is missing")
    rep.text("rigd diagnose on the identification record, with the same fit settings (so its "
             "base model is the plain model above): residual analysis, every catalogue "
             "effect's signature, refits, forward selection. Nothing in it knows this plant.")
    rows = []
    for f in d["findings"]:
        if f["significant"] or f["fit_percent_with"] is not None:
            fw = f["fit_percent_with"]
            rows.append([f["submodel"], f["effect"], "named" if f["significant"] else "no",
                         f"{f['score']:.3f}", "" if fw is None else f"{fw:.2f}",
                         f["explanation"]])
    rep.table(["sub-model", "effect", "significant", "score", "fit with it (%)", "evidence"],
              rows)
    for sub, steps in (d["steps"] or {}).items():
        if len(steps) > 1:
            rep.text(f"{sub}: the error falls (diagnose's validation part) "
                     + " → ".join(f"{'base' if x['added'] is None else '+ ' + x['added']} "
                                  f"{x['fit_percent']:.2f} %" for x in steps))
    for sub in ("actuator", "bearing"):
        for name in st.named.get(sub, []):
            png = out / "diagnose" / f"{sub}_with_{name}.png"
            if png.exists():
                rep.image(_rel(out, png), f"{sub}: the residual before and after adding "
                          f"{name} (diagnose's validation part)", href="diagnose/index.html")
    if not d["named"]:
        rep.text("The diagnosis names nothing on this record: the plain models stay.")
    for u in d["unexplained"]:
        rep.text(f"Left unexplained ({u['submodel']}): {u['text']}")
    rep.links([("diagnose/index.html", "interactive diagnosis (switch effects on and off)"),
               ("diagnose/figures.html", "its figures")], "Diagnosis: ")


def _error_falls(rep: Report, out: Path, st) -> None:
    rep.heading("4. Add what is named: the error falls on the held-out record")
    rep.text("Each sub-model identified again with the effects named for it "
             "(rigd identify --add), then both models simulated on the held-out record:")
    rows = []
    for n, b in st.fit_before.items():
        a = st.fit_after[n]
        added = ", ".join(st.named.get(n, []) + [e for e in st.extra
                                                 if e not in st.named.get(n, [])]) or "–"
        rows.append([n, added, f"{b:.2f}", f"{a:.2f}",
                     f"{100 - b:.2f} → {100 - a:.2f} ({(100 - b) / max(100 - a, 1e-9):.1f}×)"])
    rep.table(["sub-model", "added", "fit before (%)", "fit after (%)", "error"], rows)
    subs = [n for n in ("actuator", "bearing") if n in st.before.comparisons]
    fig, ax = rep.figure("heldout", "The held-out record (an excerpt, first output of each "
                         "sub-model): measured, plain model and model with the named effects "
                         "(top); their residuals (bottom)", nrows=2, ncols=len(subs),
                         sharex="col", figsize=(9, 5.5), squeeze=False)
    for k, n in enumerate(subs):
        cb, ca = st.before.comparisons[n], st.after.comparisons[n]
        dat = cb.data
        sl = _excerpt(dat.n, dat.fs)
        t = np.arange(dat.n)[sl] / dat.fs
        o = dat.output_names[0]
        ax[0, k].plot(t, dat.y[sl, 0], "k", lw=0.9, label=f"{o} measured")
        ax[0, k].plot(t, cb.yhat[sl, 0], lw=0.8, label=f"plain ({np.mean(cb.fit):.1f} %)")
        ax[0, k].plot(t, ca.yhat[sl, 0], lw=0.8, label=f"with effects ({np.mean(ca.fit):.1f} %)")
        ax[1, k].plot(t, dat.y[sl, 0] - cb.yhat[sl, 0], lw=0.8, label="residual, plain")
        ax[1, k].plot(t, ca.data.y[sl, 0] - ca.yhat[sl, 0], lw=0.8,
                      label="residual, with effects")
        ax[0, k].set_title(n, fontsize=9)
        ax[1, k].set_xlabel("time (s)")
        for a in ax[:, k]:
            a.legend(loc="upper right", fontsize=7)
            a.grid(True, alpha=0.3)
    rep.links([("compare_after/index.html", "interactive comparison"),
               ("compare_after/figures.html", "all its figures"),
               ("G_p.yaml", "the model file the design uses")], "Models with the effects: ")


def _design(rep: Report, out: Path, s: dict) -> None:
    rep.heading("5. H∞ design on the improved model (paper Figs. 3–5)")
    rob = s["robustness"]
    rep.text("Mixed-sensitivity H∞ on the design-point model with the named effects, a "
             f"{s['design_method']} controller of order {s['controller_order']} (full order "
             f"{s['controller_order_full']}), Tustin at the loop rate; robustness over "
             f"{rob['n_realizations']} random operating points of {s['robustness_model']}.")
    if s.get("design_comparison_failed"):
        rep.text("The side-by-side with the truncated full-order design FAILED: "
                 f"{s['design_comparison_failed']}")
    eff = s.get("design_model_effects") or {}
    rows = [[sub, ", ".join(e["included"]) or "–",
             "; ".join(f"{n}: {why}" for n, why in e["left_out"].items()) or "–"]
            for sub, e in eff.items()]
    if rows:
        rep.text("What of the named effects the linear design model carries (a delay as a "
                 "Padé approximant, an extra mode as a parallel mode, lags), and what it "
                 "leaves out and why:")
        rep.table(["sub-model", "in the design model", "left out"], rows)
    rep.table(["quantity", "value"], [
        ["γ (worst over the design set)", f"{s['gamma']:.3f}"],
        ["all closed loops stable", str(rob["all_stable"])],
        ["peak σ̄(S_o)", f"{s['sensitivity_peak_max']:.2f} at {s['sensitivity_peak_hz']:.0f} Hz"],
        ["S_o reduction at each resonance (mode direction / σ̄)",
         f"{s['sensitivity_reduction_at_resonance_mode_direction_min']:.2f} / "
         f"{s['sensitivity_reduction_at_resonance_min']:.2f}"],
        ["disturbance-peak reduction", f"{s['disturbance_peak_reduction_min']:.2f}"],
        ["max σ̄(S_o) below 20 Hz", f"{s['sensitivity_lowfreq_max']:.3f}"],
        ["S_o reduction over the whole band", f"{s['sensitivity_reduction_min']:.2f}"]])
    for name, cap in (("weights", "Fig. 3: the weights"),
                      ("sensitivity", "Fig. 4: σ̄(S_o) over the operating range"),
                      ("controller", "Fig. 5: the reduced K(z) against the full-order K(s)")):
        png = out / "design" / f"{name}.png"
        if png.exists():
            rep.image(_rel(out, png), cap, href="design/index.html")
    modes = out / "g_bear_report" / "modes.png"
    if modes.exists():
        rep.image(_rel(out, modes), "The operating-range sweep: identified bearing modes "
                  "versus Ω and P_I (the reassembled model of the robustness check)",
                  href="g_bear_report/index.html")
    rep.links([("design/index.html", "design report"), ("controller.yaml", "controller file")]
              + ([("g_bear_report/index.html", "sweep report")] if modes.exists() else []),
              "Design: ")


def _impacts(rep: Report, out: Path, s: dict) -> None:
    rep.heading("6. Proof: impacts with K∞ off and on (paper Figs. 6–7)")
    rep.text("K∞ is loaded into the loop (validated, closed loop re-checked); a 1 ms force "
             "pulse hits the journal at rest (Ω = 0) at 4 and 7 bar on each axis, with K∞ "
             "off and on; the damping ratio is fitted to each ring-down.")
    rep.table(["impact", "ζ K∞ off", "ζ K∞ on", "increase"],
              [[k, f"{s['damping_ratio_open'][k]:.4f}", f"{s['damping_ratio_closed'][k]:.4f}",
                f"{s['damping_increase'][k]:.2f}×"] for k in s["damping_ratio_open"]])
    links = []
    for d in sorted((out / "impact_report").glob("*")):
        for png in sorted(d.glob("*.png")):
            rep.image(_rel(out, png), f"Impact {d.name}: displacement, valve reference and "
                      "force, K∞ off and on", href=_rel(out, d / "index.html"))
        links.append((_rel(out, d / "index.html"), d.name))
    rep.links(links, "Impact reports: ")


def write_index(out: Path, s: dict[str, Any], story, recs: dict[str, Any]) -> Path:
    """Write ``out/index.html`` from the summary, the modelling step and the records."""
    rep = Report(out, "rigd demo: from records to a controller that damps the rotor")
    rep.text(f"The whole workflow in lock-step on the simulated rig ({s['plant']}, "
             f"{s['config']}): record, identify, compare with measurement, diagnose what the "
             "model misses, add it and watch the error fall, design K∞ on the improved "
             "model, deploy it and show the damping increase. All numbers: summary.json.")
    rep.links([("summary.json", "summary.json")], "Numbers: ")
    _records(rep, out, s, recs)
    if story is not None:
        _plain_model(rep, out, story)
        _diagnosis(rep, out, story)
        _error_falls(rep, out, story)
    _design(rep, out, s)
    _impacts(rep, out, s)
    return rep.write()


__all__ = ["write_index"]
