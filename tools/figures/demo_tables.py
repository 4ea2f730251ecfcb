"""The demo's tables (modelling step, impacts, design over the operating range) from the
figures of ``docs/figures/demo.json`` (a selection of ``demo-out/summary.json``), for
``docs/figures.md``."""

from __future__ import annotations

PAPER = {"open": (0.0567, 0.0282), "closed": (0.173, 0.1668), "increase": ("3", "6")}


def _z(s: dict, kind: str, p: int, ax: str) -> float:
    return s[f"damping_ratio_{kind}" if kind != "increase" else "damping_increase"][
        f"P{p}bar_W0rpm_{ax}"]


def _row(s, kind, label, fmt):
    cells = [" / ".join(fmt.format(_z(s, kind, p, ax)) for ax in "xy") for p in (4, 7)]
    paper = " / ".join(str(v) for v in PAPER[kind])
    return f"| {label} | {cells[0]} | {cells[1]} | {paper} |"


def _diagnosis(s: dict) -> list[str]:
    """The modelling step's table: what diagnose named, held-out fit before -> after."""
    d = s.get("diagnosis")
    if not d:
        return []
    lines = ["The modelling step on the held-out record (a PRBS of another seed, in no fit; "
             "`diagnosis` in `demo-out/summary.json`):", "",
             "| sub-model | diagnose named | fit before | fit after | error (100 − fit) |",
             "|---|---|---|---|---|"]
    for sub, before in d["fit_before"].items():
        after = d["fit_after"][sub]
        named = ", ".join(f"`{n}`" for n in d["named_by_submodel"].get(sub, [])) or "nothing"
        lines.append(f"| {sub} | {named} | {before:.2f} % | {after:.2f} % | "
                     f"{100 - before:.2f} → {100 - after:.2f} |")
    return lines + [""]


def render(s: dict) -> str:
    """The README block (without markers) for a demo summary."""
    lines = _diagnosis(s)
    lines += ["| | 4 bar, 0 rpm | 7 bar, 0 rpm | paper (4 / 7 bar) |", "|---|---|---|---|",
             _row(s, "open", "impact damping ratio, K∞ off (x / y)", "{:.4f}"),
             _row(s, "closed", "impact damping ratio, K∞ on (x / y)", "{:.4f}"),
             _row(s, "increase", "increase (x / y)", "{:.2f}×"), ""]
    cmp = s.get("design_comparison") or {}
    names = [s["design_method"]] + [k for k in cmp if k != s["design_method"]]
    sides = [cmp.get(n, {}) for n in names]
    if not cmp:
        sides = [{"controller_order": s["controller_order"], "gamma": s["gamma"],
                  **s["robustness"]}]
    head = [f"{n} (order {d.get('controller_order', '?')})" for n, d in zip(names, sides)]
    lines += [f"Over {s['robustness']['n_realizations']} random operating points of the "
              "reassembled model (`demo-out/summary.json`; the truncated full-order design "
              "beside it, `design_comparison`):", "",
              "| figure | " + " | ".join(head) + " | paper |",
              "|---|" + "---|" * len(head) + "---|"]

    def row(label, key, fmt, paper="–"):
        cells = [fmt.format(d[key]) if key in d else "–" for d in sides]
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {paper} |")

    if s.get("design_comparison_failed"):
        lines[-4:-4] = [f"The truncated full-order design failed, so it is not beside it: "
                        f"{s['design_comparison_failed']}", ""]
    row("γ, worst over the design set", "gamma", "{:.3f}")
    row("all closed loops stable", "all_stable", "{}")
    row("peak σ̄(S_o) (`sensitivity_peak_max`)", "sensitivity_peak_max", "{:.3f}", "1.8")
    row("at (Hz)", "sensitivity_peak_hz", "{:.0f}", "280")
    row("low-frequency increase (`sensitivity_lowfreq_max`)", "sensitivity_lowfreq_max",
        "{:.3f}", "1.2")
    row("disturbance-peak reduction (`disturbance_peak_reduction_min`)",
        "disturbance_peak_reduction_min", "{:.2f}")
    row("S_o reduction at each resonance, mode direction "
        "(`sensitivity_reduction_at_resonance_mode_direction_min`)",
        "sensitivity_reduction_at_resonance_mode_direction_min", "{:.2f}", "3–9")
    row("the same, σ̄ (`sensitivity_reduction_at_resonance_min`)",
        "sensitivity_reduction_at_resonance_min", "{:.2f}")
    row("S_o reduction over the whole 70–190 Hz band (`sensitivity_reduction_min`)",
        "sensitivity_reduction_min", "{:.2f}")
    return "\n".join(lines)
