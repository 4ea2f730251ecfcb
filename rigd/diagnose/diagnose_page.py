"""The interactive ``rigd diagnose --report`` page: switch effects on and off, watch the error.

Every model the page shows was fitted by ``diagnose`` (:func:`rigd.diagnose.engine.diagnose_data`);
the page computes nothing, so it needs no server. Per sub-model the page data holds

* ``variants``: one :func:`rigd.diagnose.page_data.model_view` per fitted model — the base
  model, each forward-selection step (the effects added so far), and the final model with
  each remaining tested effect (its refit); each with the set of ``effects`` it contains, its
  validation fit (%), error (100 − fit), decimated simulated output and residual, residual
  spectrum, by amplitude and by shaft angle;
* ``steps``: the forward selection, fit and error before and after each step;
* ``effects``: every tested effect with its finding (significant, score, evidence) — the
  page's toggles; checking a set of effects shows the variant with exactly that set (or says
  that ``diagnose`` did not fit that combination);
* ``cannot_reveal``, ``unexplained``, ``tests``: as in ``rigd diagnose --json``; ``marks``:
  where the unexplained structure lies (a frequency band, a stretch of time) on the plots.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rigd.diagnose import wording as W
from rigd.diagnose.page_data import measured_view, model_view, resonances_below_nyquist
from rigd.htmlpage import write_page


def effects_of(structure) -> list[str]:
    """Catalogue names of the effects a (possibly extended) structure contains, in order."""
    return list(structure.effects)


def _variant(t, ctx, yhat, sl, label: str, effects: list[str], kind: str) -> dict[str, Any]:
    v = model_view(t, ctx.y, np.asarray(yhat, float), ctx.fs, sl, ctx.phi)
    v.update(label=label, effects=effects, kind=kind)
    return v


def variants(sd) -> list[dict[str, Any]]:
    """The models of one :class:`~rigd.diagnose.engine.SubDiagnosis`, base first, then the
    forward-selection steps, then the final model with each other effect refitted."""
    ctx = sd.ctx
    t = np.arange(ctx.n) / ctx.fs
    out, seen = [], set()
    for i, st in enumerate(sd.steps):
        eff = effects_of(st.structure)
        label = "base model" if st.added is None else "+ " + " + ".join(eff)
        v = _variant(t, ctx, st.yhat, ctx.val, label, eff, "step")
        v["step"] = i
        out.append(v)
        seen.add(frozenset(eff))
    for name, ref in sd.refits.items():
        eff = effects_of(ref.structure)
        if frozenset(eff) in seen or name not in eff:
            continue
        seen.add(frozenset(eff))
        label = ("base model" if len(eff) == 1 else "final model") + f" + {name} (tried)"
        out.append(_variant(t, ctx, ref.yhat, ctx.val, label, eff, "tried"))
    return out


def _effects(sd, vs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    fitted = {e for v in vs for e in v["effects"]}
    out = []
    for f in sd.findings:
        d = f.to_json(False)
        d["name"] = f.effect
        d["step"] = f.evidence.get("step") if f.significant else None
        d["evidence"] = {k: v for k, v in f.evidence.items() if k != "step"}
        d["toggle"] = f.effect in fitted
        out.append(d)
    return out


def unexplained_marks(unexplained: list[dict], window: tuple[int, int], fs: float,
                      n: int) -> list[dict[str, Any]]:
    """Where the unexplained structure lies, as marks on the page's plots.

    A frequency band (``where.band_hz``, Hz) becomes a ``band`` on the residual spectrum; a
    stretch of samples (``where.samples``, counted from the record's start) a ``time`` span
    on the time plot, in the page's time base (s from the first analysed sample, so minus
    ``window[0]``), clipped to the ``n`` analysed samples.
    """
    marks = []
    for u in unexplained:
        where = u.get("where") or {}
        short = str(u.get("text", "")).split(":")[0]
        band = where.get("band_hz")
        if band and len(band) == 2 and 0 <= band[0] < band[1]:
            marks.append({"kind": "band", "lo": float(band[0]),
                          "hi": min(float(band[1]), fs / 2), "text": short})
        smp = where.get("samples")
        if smp and len(smp) == 2:
            a = min(max(int(smp[0]) - window[0], 0), n - 1)
            b = min(max(int(smp[1]) - window[0], 0), n - 1)
            if b > a:
                marks.append({"kind": "time", "t0": a / fs, "t1": b / fs, "text": short})
    return marks


def part_data(sd) -> dict[str, Any]:
    """Page data of one :class:`~rigd.diagnose.engine.SubDiagnosis`."""
    ctx = sd.ctx
    t = np.arange(ctx.n) / ctx.fs
    vs = variants(sd)
    steps = []
    for i, (st, v) in enumerate(zip(sd.steps, vs)):
        prev = sd.steps[i - 1].fit_percent if i else None
        steps.append({"added": st.added, "fit_percent": float(st.fit_percent),
                      "error_percent": 100.0 - float(st.fit_percent),
                      "fit_before": prev, "error_before": None if prev is None else 100 - prev,
                      "variant": i, "residual_rms": v["residual_rms"]})
    return {
        "name": sd.submodel,
        "fs": ctx.fs,
        "inputs": list(ctx.input_names),
        "outputs": list(ctx.output_names),
        "val_s": [float(t[ctx.val][0]), float(t[ctx.val][-1])],
        "window": list(sd.window),
        "peaks_hz": resonances_below_nyquist(ctx.resonances_hz, ctx.fs),
        "peaks_label": W.peaks_label(ctx.domain),
        "measured": measured_view(t, ctx.y, ctx.fs, ctx.val),
        "variants": vs,
        "steps": steps,
        "effects": _effects(sd, vs),
        "cannot_reveal": [c.to_json(False) for c in sd.cannot_reveal],
        "unexplained": list(sd.unexplained),
        "marks": unexplained_marks(sd.unexplained, sd.window, ctx.fs, ctx.n),
        "tests": sd.tests,
        "order": sd.order,
    }


def page_data(diag, figures: list[str]) -> dict[str, Any]:
    """Page data of a :class:`rigd.diagnose.diagnosis.Diagnosis`."""
    return {"kind": "diagnose", "title": f"Diagnosis of {Path(diag.source).name}",
            "notes": list(diag.notes), "figures": figures,
            "parts": [part_data(sd) for sd in diag.parts]}


def write_diagnose_page(diag, out: str | Path, figures: list[str]) -> Path:
    """Write the interactive page ``out/index.html``; ``figures`` are the PNG names beside it."""
    data = page_data(diag, figures)
    return write_page(out, data["title"], data)
