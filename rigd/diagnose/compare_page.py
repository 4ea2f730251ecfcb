"""The interactive ``rigd compare --report`` page: measured vs model, where the residual lies.

For each sub-model compared (:func:`rigd.ident.compare.compare_model`): the fit and residual
statistics per output, measured and simulated outputs over the whole record (zoomable,
min/max decimated), the residual ε = y − ŷ, its spectrum with the model's resonances below
Nyquist marked, its RMS by amplitude and, when the record carries the shaft angle φ, its mean
by angle (polar). The PNG report (for papers) is written beside it as ``figures.html``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rigd.diagnose import domain as D
from rigd.diagnose import wording as W
from rigd.diagnose.engine import model_resonances
from rigd.diagnose.page_data import measured_view, model_view, resonances_below_nyquist
from rigd.htmlpage import write_page
from rigd.ident.iddata import get_phi
from rigd.ident.model import base_of


def _resonances(c) -> list[float]:
    """Resonances (Hz) of the compared model's linear part (effect wrappers skipped)."""
    base, th = c.structure, np.asarray(c.theta)
    base = base_of(base)
    return model_resonances(base, th[:len(base.names)]) if base is not None else []


def _domain(c) -> str:
    """The compared model's domain (rigd.diagnose.domain) from its sub-model and poles."""
    return D.decide(c.name, {}, c.structure, np.asarray(c.theta)).name


def part_data(c) -> dict[str, Any]:
    """Page data of one :class:`rigd.ident.compare.Comparison`."""
    d = c.data
    y, yhat = np.asarray(d.y, float), np.asarray(c.yhat, float)
    t = np.arange(d.n) / d.fs
    sl = slice(0, d.n)
    view = model_view(t, y, yhat, d.fs, sl, get_phi(d))
    view.update(label="model", effects=list(c.structure.effects))
    return {
        "name": c.name,
        "fs": float(d.fs),
        "inputs": list(d.input_names),
        "outputs": list(d.output_names),
        "val_s": None,
        "table": [{"output": o, "fit_percent": float(f), **{k: c.residual[o][k] for k in
                                                            ("rms", "mean", "autocorr_lag1")
                                                            if k in c.residual[o]}}
                  for o, f in zip(d.output_names, c.fit)],
        "peaks_hz": resonances_below_nyquist(_resonances(c), d.fs),
        "peaks_label": W.peaks_label(_domain(c)),
        "measured": measured_view(t, y, d.fs, sl),
        "variants": [view],
    }


def page_data(comps: dict[str, Any], title: str, figures: list[str],
              warnings: list[str] | None = None) -> dict[str, Any]:
    """Page data of a comparison (sub-model name -> Comparison); ``warnings``: the model's
    sanity warnings (:func:`rigd.ident.sanity.file_warnings`), shown first."""
    return {"kind": "compare", "title": title,
            "notes": [f"WARNING {w}" for w in warnings or []]
            + ["Fit = 100·(1 − ‖y − ŷ‖/‖y − mean(y)‖) per output, ŷ simulated from "
               "the inputs only (initial state estimated on this record)."],
            "figures": figures, "parts": [part_data(c) for c in comps.values()]}


def write_compare_page(comps: dict[str, Any], out: str | Path, title: str,
                       warnings: list[str] | None = None) -> Path:
    """Write ``out/index.html`` (interactive) and ``out/figures.html`` with the PNGs;
    ``warnings`` (the model's sanity warnings) come first on both.

    Returns the path of ``index.html``.
    """
    from rigd.htmlreport import Report
    from rigd.ident.compare import add_figures

    rep = Report(out, title)
    for w in warnings or []:
        rep.text(f"WARNING {w}")
    add_figures(rep, comps)
    rep.write("figures.html")
    return write_page(out, title, page_data(comps, title, [p.name for p in rep.figures],
                                            warnings))
