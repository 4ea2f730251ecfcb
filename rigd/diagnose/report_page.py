"""The diagnosis report: the interactive page (``index.html``,
:mod:`rigd.diagnose.diagnose_page`) and, for papers, the PNG figures with their page
(``figures.html``): base fit, where the model fails, ranked findings with their evidence, and
before/after comparisons for the top findings."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rigd.diagnose import residual as R
from rigd.diagnose import wording as W
from rigd.htmlreport import Report


def write_report(diag, out: str | Path) -> Path:
    """Write the report of a :class:`rigd.diagnose.diagnosis.Diagnosis` into ``out``.

    ``index.html`` is the interactive page, ``figures.html`` the PNG figures; returns the
    path of ``index.html``.
    """
    from rigd.diagnose.diagnose_page import write_diagnose_page

    rep = Report(out, f"Diagnosis of {Path(diag.source).name}")
    for note in diag.notes:
        rep.text(note)
    for sd in diag.parts:
        _part(rep, sd)
    rep.write("figures.html")
    return write_diagnose_page(diag, out, [p.name for p in rep.figures])


def _part(rep: Report, sd) -> None:
    """The section of one sub-model: the tables, then the figures of its base model's
    residual (time, frequency, amplitude and direction, angle, correlation tests) and of
    each forward-selection step."""
    _tables(rep, sd)
    _time_figure(rep, sd)
    _spectrum_figure(rep, sd)
    _amplitude_figure(rep, sd)
    _angle_figure(rep, sd)
    _correlation_figure(rep, sd)
    _step_figures(rep, sd)


def _fit_with(f) -> str:
    """A finding's fit with it (%), flagged when its refit cannot be ranked."""
    if f.fit_percent_with is None:
        return ""
    flag = f.evidence.get("refit_flag")
    return f"{f.fit_percent_with:.1f}" + (f" (flagged: {flag}, not ranked)" if flag else "")


def _tables(rep: Report, sd) -> None:
    """Heading, the error falling step by step, the findings, cannot-tell and unexplained."""
    rep.heading(f"{sd.submodel} model: validation fit {sd.fit_percent:.1f} %")
    if len(sd.steps) > 1:
        rep.text("Watch the error fall (forward selection, validation fit): "
                 + " -> ".join(f"{'base' if st.added is None else '+ ' + st.added} "
                               f"{st.fit_percent:.1f} % (error {100 - st.fit_percent:.1f})"
                               for st in sd.steps))
    rows = [[f.effect, "yes" if f.significant else "no", f"{f.score:.2f}",
             f"{f.signature_score:.2f}", _fit_with(f), f.explanation]
            for f in sd.findings]
    rep.table(["effect", "significant", "score", "signature", "fit with it %", "evidence"], rows)
    for c in sd.cannot_reveal:
        rep.text(f"Cannot tell {c.effect}: {c.why}. Experiment: {c.experiment}.")
    for u in sd.unexplained:
        rep.text(f"Unexplained: {u['text']}.")


def _time_figure(rep: Report, sd) -> None:
    """Measured vs simulated output, residual, and residual RMS by segment."""
    ctx, v = sd.ctx, sd.ctx.val
    t = np.arange(ctx.n) / ctx.fs
    r = ctx.residual
    fig, ax = rep.figure(f"{sd.submodel}_time", "Measured and simulated output (validation "
                         "part), residual, and residual RMS by segment of the whole record",
                         nrows=3)
    ax[0].plot(t[v], ctx.y[v, 0], lw=0.6, label=f"measured {ctx.label(0)}")
    ax[0].plot(t[v], ctx.yhat[v, 0], lw=0.6, label="base model")
    ax[0].legend(loc="upper right")
    ax[1].plot(t[v], r[v], lw=0.5)
    ax[1].set_ylabel("residual")
    seg = R.by_segment(r, 20)
    ax[2].bar(np.arange(20), seg)
    ax[2].set_xlabel("segment (1/20 of the record)")
    ax[2].set_ylabel("residual RMS")


def _spectrum_figure(rep: Report, sd) -> None:
    """Residual spectrum (base and final model) against the measured output's."""
    ctx, v = sd.ctx, sd.ctx.val
    f, prr, pyy = R.spectra(ctx.residual[v], ctx.y[v], ctx.fs)
    fig, ax = rep.figure(f"{sd.submodel}_spectrum", "Residual spectrum against the measured "
                         f"output's; dashed: {W.peaks_label(ctx.domain)}")
    ax.semilogy(f, np.atleast_2d(pyy.T).T.sum(axis=1), label="measured output")
    ax.semilogy(f, np.atleast_2d(prr.T).T.sum(axis=1), label="residual (base)")
    if len(sd.steps) > 1:
        rw = (ctx.y - sd.final.yhat)[v]
        _, pw, _ = R.spectra(rw, ctx.y[v], ctx.fs)
        ax.semilogy(f, np.atleast_2d(pw.T).T.sum(axis=1),
                    label="residual with " + ", ".join(st.added for st in sd.steps[1:]))
    for fr in ctx.resonances_hz:
        ax.axvline(fr, ls="--", c="k", lw=0.8)
    ax.set_xlabel("Hz")
    ax.legend()


def _amplitude_figure(rep: Report, sd) -> None:
    """Residual RMS against amplitude, and the mean residual by direction of input motion."""
    ctx, v = sd.ctx, sd.ctx.val
    r = ctx.residual
    a = np.abs(ctx.yhat[v] - ctx.yhat[v].mean(axis=0)).max(axis=1)
    edges, rms = R.by_amplitude(r[v], a, 8)
    fig, ax = rep.figure(f"{sd.submodel}_amplitude", "Residual RMS against amplitude, and "
                         "mean residual by direction of input motion", ncols=2)
    ax[0].plot(0.5 * (edges[1:] + edges[:-1]), rms, "o-")
    ax[0].set_xlabel("|model output|")
    ax[0].set_ylabel("residual RMS")
    d = R.by_direction(r[v], ctx.u[v, 0])
    ax[1].bar(["rising", "falling", "holding"], [float(np.mean(d[k])) for k in
                                                  ("rising", "falling", "holding")])
    ax[1].set_title(f"by direction of {ctx.label(0, 'in')}")


def _angle_figure(rep: Report, sd) -> None:
    """Mean residual against shaft angle (records with an angle only)."""
    ctx = sd.ctx
    if ctx.phi is None:
        return
    cen, mean = R.by_angle(ctx.residual, ctx.phi)
    fig = rep.figure(f"{sd.submodel}_polar", "Mean residual against shaft angle",
                     subplot_kw={"projection": "polar"})[0]
    axp = fig.axes[0]
    for i in range(ctx.ny):
        axp.plot(np.r_[cen, cen[0]], np.r_[mean[:, i], mean[0, i]], label=ctx.label(i))
    axp.legend()


def _correlation_figure(rep: Report, sd) -> None:
    """Whiteness and residual–input cross-correlation with their 99 % bounds."""
    ctx, v = sd.ctx, sd.ctx.val
    r = ctx.residual
    fig, ax = rep.figure(f"{sd.submodel}_resid", "Whiteness and residual–input "
                         "cross-correlation with 99 % bounds (as MATLAB resid)", ncols=2)
    w = R.whiteness(r[v, 0])
    ax[0].stem(w.lags, w.rho)
    ax[0].axhline(w.bound, c="r", ls="--")
    ax[0].axhline(-w.bound, c="r", ls="--")
    ax[0].set_title(f"autocorrelation of {ctx.label(0)} residual")
    c = R.cross_correlation(r[v, 0], ctx.u[v, 0])
    ax[1].stem(c.lags, c.rho)
    ax[1].axhline(c.bound, c="r", ls="--")
    ax[1].axhline(-c.bound, c="r", ls="--")
    ax[1].set_title(f"{ctx.label(0)} residual vs {ctx.label(0, 'in')}")


def _step_figures(rep: Report, sd) -> None:
    """Residual before and after each forward-selection step."""
    ctx, v = sd.ctx, sd.ctx.val
    t = np.arange(ctx.n) / ctx.fs
    for prev, st in zip(sd.steps[:-1], sd.steps[1:]):
        fig, ax = rep.figure(f"{sd.submodel}_with_{st.added}",
                             f"Adding {st.added}: fit {prev.fit_percent:.1f} % -> "
                             f"{st.fit_percent:.1f} %")
        ax.plot(t[v], (ctx.y - prev.yhat)[v, 0], lw=0.5,
                label="residual before" if prev.added is None else f"residual with {prev.added}")
        ax.plot(t[v], (ctx.y - st.yhat)[v, 0], lw=0.5, label=f"residual with {st.added}")
        ax.legend()
