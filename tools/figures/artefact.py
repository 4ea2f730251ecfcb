"""Write and read the figure artefacts (``docs/figures/*.json``) with their provenance.

Provenance is taken when the figures are saved, right after they were measured: the host
(CPU model, cores, the load average — the 1-minute figure covers the measurement of a section
or the demo's last minute, the 5-minute one the whole demo — and the load average just before
the measurement began, ``load_before``: what else the host was doing, without the
measurement's own load; the host is called ``quiet`` or ``busy`` from it), the commit and
whether the code, the configs or the pins had uncommitted changes (``tree_changed``), the UTC
date, the Python and package versions. ``RIGD_HOST_NOTE`` adds words about the host
(``"shared machine, other jobs running"``).
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

from tools.figures import FIGURES_DIR

#: packages whose versions move the figures (numerics, the loop's compiler, the web stack)
PACKAGES = ("rigd", "numpy", "scipy", "numba", "control", "h5py", "matplotlib", "plotly",
            "starlette", "uvicorn", "pydantic")

#: the paths whose uncommitted changes would make the recorded commit not what was measured
CODE_PATHS = ("rigd", "drivers", "bench", "config", "pyproject.toml", "constraints.txt")

#: the demo summary's keys kept as figures (the rest of summary.json is the run's own record)
DEMO_KEYS = ("run_time_s", "plant", "design_method", "controller_order", "gamma",
             "damping_ratio_open", "damping_ratio_closed", "damping_increase", "robustness",
             "sensitivity_peak_max", "sensitivity_lowfreq_max",
             "disturbance_peak_reduction_min",
             "sensitivity_reduction_at_resonance_mode_direction_min",
             "sensitivity_reduction_at_resonance_min", "sensitivity_reduction_min",
             "design_comparison", "design_comparison_failed", "diagnosis", "timings_s")


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _git(root: Path, *args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True,
                             timeout=30, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def provenance(root: Path, load_before: list[float] | None = None) -> dict[str, Any]:
    """Where and with what the figures were measured, now (see the module docstring).
    ``load_before``: the load averages when the measurement began (the host's own load; a
    CPU-bound measurement on 2 cores raises the 1-minute figure above 1 by itself)."""
    load = [round(v, 2) for v in os.getloadavg()]
    cores = os.cpu_count() or 1
    judged = load if load_before is None else [round(float(v), 2) for v in load_before]
    state = "busy" if judged[0] > 0.5 * cores else "quiet"
    when = "before the measurement" if load_before is not None else "after it"
    note = os.environ.get("RIGD_HOST_NOTE", "").strip()
    host = {"cpu": _cpu_model(), "cores": cores, "load": load,
            "state": f"{state}: load average {judged[0]:g} on {cores} cores {when}"
                     + (f"; {note}" if note else "")}
    if load_before is not None:
        host["load_before"] = judged
    commit = _git(root, "rev-parse", "HEAD")
    # changes to what is measured (the code, configs, pins), not to docs or tests
    dirty = _git(root, "status", "--porcelain", "--untracked-files=no", "--", *CODE_PATHS)
    packages = {}
    for name in PACKAGES:
        try:
            packages[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return {"host": host, "commit": commit or "unknown",
            "tree_changed": bool(dirty) if dirty is not None else None,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "python": platform.python_version(), "packages": packages}


def write(root: Path, name: str, command: str, figures: dict[str, Any],
          extra: dict[str, Any] | None = None, load_before: list[float] | None = None) -> Path:
    """Write ``docs/figures/<name>.json`` (atomically: a temporary file renamed over it)."""
    measured = provenance(root, load_before)
    measured.update(extra or {})
    doc = {"artefact": name, "command": command, "measured": measured, "figures": figures}
    path = root / FIGURES_DIR / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=2, sort_keys=False) + "\n")
    tmp.replace(path)
    return path


def save_bench_section(root: Path, section: str, figures: dict[str, Any],
                       seconds: float, load_before: list[float] | None = None) -> Path:
    """A ``python -m bench`` section's figures as ``bench-<section>.json``."""
    return write(root, f"bench-{section}", f"python -m bench {section}", figures,
                 {"seconds": round(seconds, 1)}, load_before)


def save_demo(root: Path, summary_path: Path, load_before: list[float] | None = None) -> Path:
    """The figures of a ``rigd demo`` run (its ``summary.json``) as ``demo.json``."""
    summary = json.loads(Path(summary_path).read_text())
    figures = {k: summary[k] for k in DEMO_KEYS if k in summary}
    return write(root, "demo", "make demo", figures,
                 {"threads": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS",
                                                              "OPENBLAS_NUM_THREADS")}},
                 load_before)


def load_all(root: Path) -> dict[str, dict[str, Any]]:
    """Every artefact of ``docs/figures/`` by name, in name order."""
    out = {}
    for path in sorted((root / FIGURES_DIR).glob("*.json")):
        doc = json.loads(path.read_text())
        out[doc.get("artefact", path.stem)] = doc
    return out
