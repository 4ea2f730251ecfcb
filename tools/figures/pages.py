"""Render ``docs/figures.md`` and the README's figures table from the artefacts.

Each figure is one row: its name (the key in the JSON; a nested value as ``key.sub``), its
value, what it is, the command that measures it and the artefact that holds it; the
artefacts' provenance (host, load, packages) is one table at the top of ``docs/figures.md``
and nowhere else; the commit and the date stay in the JSON, out of the pages. The README's
table shows a few values and their commands only, and links here.
"""

from __future__ import annotations

from typing import Any

from tools.figures.demo_tables import render as demo_tables

BEGIN, END = "<!-- figures:begin -->", "<!-- figures:end -->"

#: what a figure is (and its target, where the project set one); keys not listed are shown
#: with their name only
WHAT: dict[str, str] = {
    "lockstep_cycles_per_s": "whole cycle (sim plant + PD + K∞ + HDF5 recording of every "
                             "frame) on the lock-step clock",
    "loop_compute_us": "one cycle's compute with a 4th-order K∞ (the order `make demo` "
                       "deploys), µs",
    "loop_compute_us_k14": "the same with a 14-state K∞, µs",
    "loop_kernel_ns": "the numba cycle kernel alone (mapping, 4 PD loops, K∞ update), ns",
    "loop_kernel_ns_k14": "the same with a 14-state K∞, ns",
    "rt_lateness_us": "wake-up lateness at 5 kHz on the real-time clock, µs",
    "rt_compute_us": "one cycle's compute on the real-time clock, µs",
    "rt_miss_fraction": "cycles that missed their deadline on the real-time clock",
    "op_change_miss_fraction": "deadline misses with an operating-point change every 100 ms "
                               "(target: ≤ the idle figure + 1e-3)",
    "op_change_idle_miss_fraction": "the same run's idle blocks",
    "identify_bearing_s": "bearing model by PEM on 30,000 samples, s (target ≤ 3 s)",
    "identify_bearing_fit_percent": "that model's fit, %",
    "diagnose_60s_s": "`diagnose` of a 60 s rotor record with a hidden cubic stiffness, s",
    "diagnose_60s_top": "the effect it ranks first",
    "diagnose_generic_order_auto_s": "`diagnose --order auto` on a 40,000-sample record of a "
                                     "3-mass chain, s (target ≤ 20 s)",
    "diagnose_generic_order_auto_modes": "modes it finds (of 3)",
    "diagnose_generic_order_auto_fit": "its base model's fit, %",
    "diagnose_mimo_s": "`diagnose --order auto` on an 8,000-sample record with 2 inputs of a "
                       "3-mode structure, s (target ≤ 30 s)",
    "structure_diagnose_s": "`diagnose` of a 3-accelerometer × 70,000-sample record of a "
                            "5-mode structure with a bolted joint, s (target ≤ 120 s)",
    "structure_diagnose_analysed_n": "samples it analyses (its window)",
    "structure_diagnose_top": "the effect it names first",
    "structure_diagnose_top_hz": "the mode it names it at, Hz",
    "structure_joint_hz": "the joint mode's apparent frequency in the record, Hz",
    "structure_diagnose_fit": "the diagnosed model's held-out fit, %",
    "structure_identify_s": "`identify` of the same record, s (target ≤ 60 s)",
    "structure_identify_fit": "its held-out fit, %",
    "design_chain_s": "full-order H∞ design → reduction → Tustin, s",
    "robustness_30_s": "S_o over 30 operating points, s",
    "design_structured_s": "full-order synthesis + fixed-order tuning of the order-4 K∞, s "
                           "(target ≤ 60 s)",
    "design_structured_tuning_s": "its fixed-order tuning alone, s",
    "reynolds_lockstep_cycles_per_s": "the physics-grade plant in the lock-step loop "
                                      "(target ≥ 5000)",
    "reynolds_step_us": "one step of the physics-grade plant, µs",
    "export_peak_mb": "peak RSS of HDF5 → interchange CSV, 3 M frames, MB (target < 200)",
    "export_s": "time of that export, s",
    "socket_busy_status_ms": "`status` latency while a 2 s command is pending and 20 clients "
                             "hammer the socket, ms (target p99 ≤ 50)",
    "web_stream_latency_ms": "console stream latency, loop publication → client, ms "
                             "(target p99 ≤ 100)",
    "safe_click_latency_ms": "console SAFE click → latched, ms (target p99 ≤ 100)",
    "console_tab_cpu_percent": "CPU of the console tab's renderer, % of a core "
                               "(target ≤ 15)",
    "hostile_load_miss_fraction": "deadline misses under the hostile load (target: ≤ the "
                                  "idle figure + 1e-3)",
    "safe_latency_ms": "SAFE latency under the hostile load, ms (target p99 ≤ 50)",
    "run_time_s": "`rigd demo` from start to the story page, s",
}

#: the README's short table: (figure, artefact, label)
README_ROWS: tuple[tuple[str, str, str], ...] = (
    ("lockstep_cycles_per_s", "bench-loop", "loop cycles per second, lock-step"),
    ("loop_compute_us.p99", "bench-loop", "one cycle's compute, p99 (µs)"),
    ("rt_miss_fraction", "bench-loop", "real-time deadline misses at 5 kHz"),
    ("identify_bearing_s", "bench-identify", "identify the bearing model (s)"),
    ("diagnose_60s_s", "bench-diagnose", "diagnose a 60 s rotor record (s)"),
    ("diagnose_mimo_s", "bench-diagnose", "diagnose a 2-input record, order auto (s)"),
    ("design_structured_s", "bench-design", "structured H∞ design of the order-4 K∞ (s)"),
    ("reynolds_lockstep_cycles_per_s", "bench-reynolds",
     "physics-grade plant, cycles per second"),
    ("run_time_s", "demo", "`make demo`, the whole story (s)"),
)


def fmt(v: Any) -> str:
    """One value as the pages show it."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}".replace(",", " ") if abs(v) >= 10_000 else str(v)
    if isinstance(v, float):
        if v != v or v in (float("inf"), float("-inf")):
            return str(v)
        if abs(v) >= 10_000:
            return f"{v:,.0f}".replace(",", " ")
        if v == 0 or abs(v) >= 0.01:
            return f"{v:.4g}"
        return f"{v:.2e}"
    if isinstance(v, str):
        return f"`{v}`"
    if isinstance(v, (list, tuple)):
        return ", ".join(fmt(x) for x in v) if len(v) <= 8 else f"{len(v)} values"
    if v is None:
        return "–"
    return str(v)


def flatten(figures: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """(name, value) of every figure; a nested dict's values as ``key.sub``."""
    out = []
    for k, v in figures.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            out.extend(flatten(v, name + "."))
        else:
            out.append((name, v))
    return out


def lookup(figures: dict[str, Any], name: str) -> Any:
    v: Any = figures
    for part in name.split("."):
        if not isinstance(v, dict) or part not in v:
            raise KeyError(name)
        v = v[part]
    return v


def _what(name: str) -> str:
    return WHAT.get(name) or WHAT.get(name.split(".")[0], "")


def _provenance_table(artefacts: dict[str, dict]) -> list[str]:
    """Where each artefact was measured: host (CPU, cores, quiet or busy), load and packages.
    The commit, the date and any ``RIGD_HOST_NOTE`` stay in the JSON (the page is for users,
    the JSON is the provenance record)."""
    lines = ["| artefact | command | host | load (1 / 5 / 15 min) | Python, packages |",
             "|---|---|---|---|---|"]
    for name, doc in artefacts.items():
        m = doc["measured"]
        h = m["host"]
        state = str(h.get("state", "")).split(":")[0].strip()
        pk = ", ".join(f"{k} {v}" for k, v in m.get("packages", {}).items())
        load = " / ".join(f"{x:g}" for x in h.get("load", []))
        lines.append(f"| `docs/figures/{name}.json` | `{doc['command']}` | {h['cpu']}, "
                     f"{h['cores']} cores, {state} | {load} | "
                     f"Python {m.get('python', '?')}; {pk} |")
    return lines


def render_figures_md(artefacts: dict[str, dict], sections: list[str]) -> str:
    """The whole of ``docs/figures.md``. ``sections``: the benchmark sections ``make bench``
    runs (those without an artefact are listed as not measured)."""
    out = ["# Figures", "",
           "<!-- generated by `python -m tools.figures` from docs/figures/*.json: do not edit "
           "by hand -->", "",
           "Every figure the project quotes, one value each, with the command that measures "
           "it and where it was measured.", "",
           "## Re-measure and re-render", "", "```sh",
           "make bench                    # every benchmark section: docs/figures/bench-*.json",
           "python -m bench --save loop   # one section",
           "make demo                     # the demo: docs/figures/demo.json",
           "make figures                  # render this page and the README table again",
           "```", "",
           "`make bench` and `make demo` render the pages themselves after saving; commit the "
           "JSON files with the pages. `make test` checks that the pages match the committed "
           "JSON (`tests/test_figures_pages.py`). Each JSON file also records the commit, the "
           "date and, with `RIGD_HOST_NOTE=\"...\"`, words about the host.", "",
           "## Where they were measured", ""]
    out += _provenance_table(artefacts)
    demo = artefacts.get("demo")
    if demo:
        out += ["", "## The demo (`make demo`)", "",
                f"`rigd demo` on the `{demo['figures'].get('plant', '?')}` plant, "
                f"{fmt(demo['figures'].get('run_time_s'))} s from start to the story page "
                "(`demo-out/index.html`).", "", demo_tables(demo["figures"])]
    out += ["", "## Benchmarks (`make bench`)", ""]
    for name, doc in artefacts.items():
        if not name.startswith("bench-"):
            continue
        out += [f"### {name[len('bench-'):]}", "",
                "| figure | value | what it is | command | artefact |", "|---|---|---|---|---|"]
        for key, v in flatten(doc["figures"]):
            out.append(f"| `{key}` | {fmt(v)} | {_what(key)} | `{doc['command']}` | "
                       f"`{name}.json` |")
        out.append("")
    missing = [s for s in sections if f"bench-{s}" not in artefacts]
    if missing:
        out += ["## Not measured in these artefacts", "",
                "Sections of `make bench` with no artefact yet (run them to add one):", ""]
        out += [f"- `python -m bench --save {s}`" for s in missing]
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def render_readme_table(artefacts: dict[str, dict]) -> str:
    """The README's figures table (without the markers): values and commands only."""
    lines = ["| figure | value | command |", "|---|---|---|"]
    for key, art, label in README_ROWS:
        doc = artefacts.get(art)
        try:
            value = fmt(lookup(doc["figures"], key)) if doc else "not measured"
        except KeyError:
            value = "not measured"
        cmd = doc["command"] if doc else ("make demo" if art == "demo"
                                          else f"python -m bench {art[len('bench-'):]}")
        lines.append(f"| {label} | {value} | `{cmd}` |")
    lines += ["", "Every figure, with where and how it was measured: "
                  "[docs/figures.md](docs/figures.md)."]
    return "\n".join(lines)


def readme_block(readme: str) -> str:
    """The README's text between the markers; ValueError when they are missing."""
    i, j = readme.find(BEGIN), readme.find(END)
    if i < 0 or j < i:
        raise ValueError(f"README has no {BEGIN} ... {END} block")
    return readme[i + len(BEGIN):j].strip("\n")


def rewrite_readme(readme: str, artefacts: dict[str, dict]) -> str:
    """The README with its figures block replaced by :func:`render_readme_table`."""
    readme_block(readme)
    i, j = readme.find(BEGIN), readme.find(END)
    return readme[:i + len(BEGIN)] + "\n" + render_readme_table(artefacts) + "\n" + readme[j:]
