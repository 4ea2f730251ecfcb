"""Figures as artefacts: what ``make bench`` and ``make demo`` measure, kept as JSON with where
it was measured, and the pages rendered from it.

* ``docs/figures/bench-<section>.json`` — one file per benchmark section (``python -m bench
  --save``, which ``make bench`` runs), ``docs/figures/demo.json`` — the demo's figures
  (``python -m tools.figures save-demo demo-out/summary.json``, which ``make demo`` runs).
  Each file: ``{"artefact", "command", "measured": {host, commit, date, packages, ...},
  "figures": {...}}`` (:mod:`tools.figures.artefact`).
* ``python -m tools.figures`` renders ``docs/figures.md`` and the README's figures table
  (between ``<!-- figures:begin -->`` and ``<!-- figures:end -->``) from those files;
  ``--check`` renders in memory and exits 1 when a committed page differs
  (:mod:`tools.figures.pages`).

Plain Python (json, platform, subprocess): no rigd import, so it runs beside any install.
"""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FIGURES_DIR = Path("docs") / "figures"
FIGURES_MD = Path("docs") / "figures.md"
README = Path("README.md")
