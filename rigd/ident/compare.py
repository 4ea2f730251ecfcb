"""Model versus measurement (MATLAB ``compare``-like) and its HTML report (paper Fig. 2).

:func:`compare_model` simulates every sub-model of a model file on a record (prefiltered as at
identification; initial state estimated by least squares, see ``x0``) and returns the
fit per output, 100·(1 − ‖y − ŷ‖/‖y − ȳ‖), and residual statistics. The *whole* given record
is used: give it held-out data (another record, or the validation part of the identification
record, ``--part validation``: by default its initial state comes from the estimation part,
so nothing is fitted on the held-out samples; ``x0="estimate"`` re-estimates it there).

:func:`write_report` makes the HTML report: measured vs simulated outputs, the inputs, the
residual ε = p_meas − p_id, time zooms of each, and the model's Bode plot over the empirical
frequency response (Welch/H1) of the data.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigd.data.record import Record
from rigd.errors import InputError
from rigd.ident.figures import REFIT_FLAGS, fit_percent, refit_flag
from rigd.ident.iddata import IdData
from rigd.ident.initial import frf
from rigd.ident.modelfile import ModelFile
from rigd.ident.prefilter import PrefilterOptions
from rigd.ident.workflow import estimate_x0, prepare, residual_stats, samples_needed


@dataclass
class Comparison:
    """Result for one sub-model."""

    name: str
    data: IdData
    yhat: np.ndarray
    fit: np.ndarray
    residual: dict[str, Any]
    theta: np.ndarray
    structure: Any = None
    extra: dict[str, Any] = field(default_factory=dict)


def _options_from(model: ModelFile, name: str) -> PrefilterOptions:
    rep = model.prefilters.get(name, {}) if isinstance(model.prefilters, dict) else {}
    offs = rep.get("offsets", True)
    n_off = offs.get("samples", 2000) if isinstance(offs, dict) else 2000
    return PrefilterOptions(offsets=bool(offs), offset_samples=int(n_off),
                            median=bool(rep.get("median", True)),
                            runout=bool(rep.get("runout", True)))


def _part(model: ModelFile, part: str, n: int, where: str) -> tuple[int, int]:
    """Samples (start, stop) of ``part`` (``estimation``/``validation``) of an ``n``-sample
    record: the model file's split fraction, or its ``--est/--val`` samples (same length
    of record only)."""
    split = model.split or {}
    if "fraction" in split or part not in split:
        k = int(round(n * float(split.get("fraction", 2 / 3))))
        return (k, n) if part == "validation" else (0, k)
    n_id = (model.data or {}).get("n_samples")
    if n_id is not None and int(n_id) != n:
        raise InputError(f"--part {part}: the model was fitted with --est/--val sample ranges "
                         f"of a {n_id}-sample record, this record has {n} samples (give "
                         "--part all with --range START:STOP)", where)
    a, b = (int(v) for v in split[part])
    return a, b


#: where the initial state (and output offsets) of a compared model come from: ``estimation``
#: (the validation part's state from the estimation part: the model runs on through both,
#: nothing is fitted on the compared samples; the default of ``--part validation``) or
#: ``estimate`` (re-estimated by least squares on the compared samples themselves)
X0_SOURCES = ("estimation", "estimate")

#: the label of each source, printed and in the JSON (``initial_state``)
X0_LABELS = {"estimation": "from the estimation part (nothing fitted on the compared samples)",
             "estimate": "re-estimated on the compared samples"}


def compare_model(model: ModelFile, record: Record, runout: Record | None = None,
                  part: str = "all", x0: str = "estimation") -> dict[str, Comparison]:
    """Compare every sub-model of ``model`` that ``record`` has columns for.

    ``part``: ``all`` (whole record), ``validation`` / ``estimation`` (the split stored in the
    model file, as a fraction of the record). ``x0`` (``--part validation`` only): the initial
    state and output offsets from the estimation part (``estimation``, default: least squares
    on the estimation part, then the model simulated on through the validation part, which
    is what the fit is measured on) or ``estimate`` (re-estimated on the validation samples
    themselves, as other records are compared). The whole record and the estimation part
    are compared with their state estimated on the compared samples. Each comparison says
    which (``extra["initial_state"]``).
    """
    if x0 not in X0_SOURCES:
        raise InputError(f"x0 must be one of {', '.join(X0_SOURCES)} (got {x0!r})", "--x0")
    if abs(model.fs - record.fs) > 1e-6 * model.fs:
        raise InputError(f"record sample rate {record.fs:g} Hz differs from the model's "
                         f"{model.fs:g} Hz", record.source)
    out = {}
    for name, sm in model.submodels.items():
        ins, outs = list(sm.structure.input_names), list(sm.structure.output_names)
        if name == "generic":
            if not record.has(*ins, *outs):
                continue
            rec = record if record.is_generic else dataclasses.replace(record, meta={
                **record.meta, "inputs": ins, "outputs": outs})
        else:
            rec = record
            if not record.has(*ins, *outs):
                continue
        need = samples_needed(sm.structure)
        data, _ = prepare(rec, name, _options_from(model, name), runout, min_samples=need)
        source = "estimate"
        if part == "all":
            theta = estimate_x0(sm.structure, sm.theta, data)
            yhat = np.asarray(sm.structure.simulate(theta, data))
        elif part == "validation" and x0 == "estimation":
            source = "estimation"
            data, theta, yhat = _run_on(model, sm, data, need, record.source)
        else:
            data = data.slice(*_part(model, part, data.n, record.source))
            _enough(data.n, need, part, name, record.source)
            theta = estimate_x0(sm.structure, sm.theta, data)
            yhat = np.asarray(sm.structure.simulate(theta, data))
        out[name] = Comparison(name, data, yhat, fit_percent(data.y, yhat),
                               residual_stats(data.y, yhat, data.output_names), theta,
                               sm.structure, {"initial_state": source})
    if not out:
        raise InputError("record has the columns of none of the model's sub-models ("
                         + ", ".join(model.submodels) + ")", record.source)
    return out


def fit_warnings(comps: dict[str, Comparison]) -> list[str]:
    """A warning for each output whose fit is below 0 % (worse than the output's mean) or
    not finite (a diverged simulation): such a figure is flagged, never read as a fit
    (:func:`rigd.ident.figures.refit_flag`'s ``below_zero`` and ``diverged``)."""
    out = []
    for name, c in comps.items():
        for o, f in zip(c.data.output_names, c.fit):
            flag = refit_flag(f, -np.inf)
            if flag is not None:
                out.append(f"{name}: {o}: fit {f:.2f} % — {REFIT_FLAGS[flag]}")
    return out


def _enough(n: int, need: int, part: str, name: str, where: str) -> None:
    if n < need:
        raise InputError(f"--part {part} has {n} samples; the {name} model needs at least "
                         f"{need} to be compared (its initial states are estimated on the "
                         "record)", where)


def _run_on(model: ModelFile, sm, data: IdData, need: int, where: str):
    """The validation part with the state from the estimation part: x0 and offsets fitted
    on the estimation samples, the model simulated from the start of the earlier of the two
    parts to the end of the later one; returns (validation data, theta, its simulation)."""
    a, b = _part(model, "validation", data.n, where)
    e0, e1 = _part(model, "estimation", data.n, where)
    _enough(e1 - e0, need, "estimation", sm.name, where)
    s0, s1 = min(a, e0), max(b, e1)
    run = data.slice(s0, s1)
    theta = estimate_x0(sm.structure, sm.theta, run, rows=slice(e0 - s0, e1 - s0))
    ysim = np.asarray(sm.structure.simulate(theta, run))
    return data.slice(a, b), theta, ysim[a - s0:b - s0]


def yardsticks(model: ModelFile, record: Record, runout: Record | None,
               fits: dict[str, float]) -> dict[str, Any]:
    """The yardstick (:func:`rigd.ident.yardstick.measure`) of each sub-model in ``fits``
    (its validation fit, %) on ``record`` with the model file's split: a plain ARX and a
    subspace model fitted on the same estimation part, scored on the same validation part.
    A sub-model whose parts do not allow it (validation before estimation) maps to None."""
    from rigd.ident.yardstick import measure

    out: dict[str, Any] = {}
    for name, fp in fits.items():
        sm = model.submodels[name]
        ins, outs = list(sm.structure.input_names), list(sm.structure.output_names)
        rec = record if (name != "generic" or record.is_generic) else dataclasses.replace(
            record, meta={**record.meta, "inputs": ins, "outputs": outs})
        data, _ = prepare(rec, name, _options_from(model, name), runout,
                          min_samples=samples_needed(sm.structure))
        est = slice(*_part(model, "estimation", data.n, record.source))
        val = slice(*_part(model, "validation", data.n, record.source))
        out[name] = measure(data.u, data.y, est, val, fp, data.fs)
    return out


def summary(comps: dict[str, Comparison]) -> dict[str, Any]:
    """JSON summary: fit per output and residual statistics per sub-model."""
    if len(comps) == 1:
        fp: Any = float(np.mean(next(iter(comps.values())).fit))
    else:
        fp = {n: float(np.mean(c.fit)) for n, c in comps.items()}
    return {"fit_percent": fp,
            "fit_per_output": {n: dict(zip(c.data.output_names, map(float, c.fit)))
                               for n, c in comps.items()},
            "residual": {n: c.residual for n, c in comps.items()},
            "n_samples": {n: c.data.n for n, c in comps.items()},
            "initial_state": {n: c.extra.get("initial_state", "estimate")
                              for n, c in comps.items()}}


def model_frequency_response(structure, theta, f_hz: np.ndarray) -> np.ndarray:
    """H(j2πf) (nf, ny, nu) of the linear part of ``structure`` at ``theta``."""
    from rigd.ident.model import linear_part_of

    lp = linear_part_of(structure, theta)
    A, B, C, D = (np.asarray(m, float) for m in (lp.A, lp.B, lp.C, lp.D))
    n = A.shape[0]
    out = np.empty((len(f_hz), C.shape[0], B.shape[1]), complex)
    for i, f in enumerate(f_hz):
        # the per-input delays: e^(−j2πf τ_j) on input j
        ph = np.exp(-2j * np.pi * f * np.asarray(lp.delays, float) / (lp.fs or np.inf))
        out[i] = (C @ np.linalg.solve(2j * np.pi * f * np.eye(n) - A, B) + D) * ph[None, :]
    return out


def write_report(comps: dict[str, Comparison], out: str | Path, title: str = "Model vs "
                 "measurement", zoom_s: float | None = None,
                 warnings: list[str] | None = None) -> Path:
    """HTML report with Fig.-2-like plots and Bode over empirical FRF; returns index path.

    ``warnings``: the model's sanity warnings, shown first.
    """
    from rigd.htmlreport import Report

    rep = Report(out, title)
    for w in warnings or []:
        rep.text(f"WARNING {w}")
    add_figures(rep, comps, zoom_s)
    return rep.write()


def add_figures(rep, comps: dict[str, Comparison], zoom_s: float | None = None) -> None:
    """Add the fit tables and the PNG figures of :func:`write_report` to ``rep``
    (a :class:`rigd.htmlreport.Report`)."""
    src = {X0_LABELS[c.extra.get("initial_state", "estimate")] for c in comps.values()}
    rep.text("Fit = 100·(1 − ‖y − ŷ‖/‖y − mean(y)‖) per output, ŷ simulated from the inputs "
             f"only (initial state {'; '.join(sorted(src))}).")
    for name, c in comps.items():
        d = c.data
        t = np.arange(d.n) / d.fs
        rep.heading(f"{name} sub-model")
        rep.table(["output", "fit %", "residual rms", "residual mean", "lag-1 autocorr"],
                  [[o, f"{f:.2f}", f"{c.residual[o]['rms']:.4g}", f"{c.residual[o]['mean']:.3g}",
                    f"{c.residual[o]['autocorr_lag1']:.3f}"]
                   for o, f in zip(d.output_names, c.fit)])
        eps = d.y - c.yhat
        z = zoom_s or min(0.1, t[-1] / 4)
        k0 = d.n // 2
        k1 = min(d.n, k0 + int(z * d.fs))
        for tag, sl in (("full", slice(None)), ("zoom", slice(k0, k1))):
            fig, ax = rep.figure(f"{name}_time_{tag}", f"{name}: measured vs model "
                                 f"({'whole record' if tag == 'full' else 'time zoom'}), inputs "
                                 "and residual ε = y − ŷ", nrows=d.ny + 2, sharex=True)
            for i, o in enumerate(d.output_names):
                ax[i].plot(t[sl], d.y[sl, i], lw=0.6, label=f"{o} measured")
                ax[i].plot(t[sl], c.yhat[sl, i], lw=0.6, label=f"{o} model")
                ax[i].legend(loc="upper right", fontsize=7)
            for j, u in enumerate(d.input_names):
                ax[d.ny].plot(t[sl], d.u[sl, j], lw=0.6, label=u)
            ax[d.ny].legend(loc="upper right", fontsize=7)
            for i, o in enumerate(d.output_names):
                ax[d.ny + 1].plot(t[sl], eps[sl, i], lw=0.6, label=f"ε {o}")
            ax[d.ny + 1].legend(loc="upper right", fontsize=7)
            ax[-1].set_xlabel("time (s)")
        try:
            f, H, coh, _ = frf(d.u, d.y, d.fs)
            Hm = model_frequency_response(c.structure, c.theta, f)
        except Exception as exc:  # noqa: BLE001 - report what could not be drawn
            rep.text(f"(no Bode plot: {exc})")
            continue
        fig, ax = rep.figure(f"{name}_bode", f"{name}: model Bode plot (lines) over the "
                             "empirical frequency response (H1, Welch; dots)",
                             nrows=2, ncols=1, sharex=True, figsize=(9, 6))
        for i in range(d.ny):
            for j in range(d.nu):
                lab = f"{d.input_names[j]}→{d.output_names[i]}"
                line, = ax[0].loglog(f, np.abs(Hm[:, i, j]), lw=1, label=lab)
                ax[0].loglog(f, np.abs(H[:, i, j]), ".", ms=2, color=line.get_color())
                ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(Hm[:, i, j]))), lw=1,
                               color=line.get_color())
                ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(H[:, i, j]))), ".", ms=2,
                               color=line.get_color())
        ax[0].set_ylabel("|H|")
        ax[0].legend(fontsize=7)
        ax[1].set_ylabel("phase (deg)")
        ax[1].set_xlabel("frequency (Hz)")
