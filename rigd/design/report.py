"""Design and impact figures (paper Figs. 3–7) on a :class:`rigd.report.Report`."""

from __future__ import annotations

import numpy as np

from rigd.design.robustness import freq_response
from rigd.design.weights import magnitude
from rigd.report import Report


def fig_weights(rep: Report, cfg) -> None:
    """Fig. 3: |W_p|, |W_u| and the bound 1/|W_p| on |S|."""
    f = np.logspace(0, np.log10(0.49 * cfg.fs_hz), 400)
    fig, ax = rep.figure("weights", "Fig. 3: weights W_p (on S) and W_u (on K S); 1/|W_p| is "
                         "the target bound on |S_o|")
    ax.loglog(f, magnitude(cfg.weights.W_p, f), label="|W_p|")
    ax.loglog(f, 1 / magnitude(cfg.weights.W_p, f), "--", label="1/|W_p|")
    ax.loglog(f, magnitude(cfg.weights.W_u, f), label="|W_u|")
    ax.axvspan(*cfg.robustness.band_hz, color="0.9")
    ax.set_xlabel("frequency (Hz)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)


def fig_sensitivity(rep: Report, rob) -> None:
    """Fig. 4: σ̄(S_o) for every realization."""
    fig, ax = rep.figure("sensitivity", f"Fig. 4: output sensitivity S_o for "
                         f"{len(rob.realizations)} realizations of the operating range; band "
                         f"{rob.band_hz[0]:g}-{rob.band_hz[1]:g} Hz shaded")
    for s in rob.sigma:
        ax.semilogx(rob.f_hz, 20 * np.log10(s), lw=0.7)
    ax.axvspan(*rob.band_hz, color="0.9")
    ax.axhline(0, color="k", lw=0.8)
    ax.axhline(20 * np.log10(1 / 3), color="r", ls="--", lw=0.8, label="1/3")
    ax.axhline(20 * np.log10(2), color="r", ls=":", lw=0.8, label="2")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("max singular value of S_o (dB)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)


def fig_controller(rep: Report, res) -> None:
    """Fig. 5: K(z) (reduced, discrete) against the full-order K(s), each element."""
    f = np.logspace(0, np.log10(0.49 * res.fs_hz), 500)
    Kf = freq_response(res.K_full, f)
    Kz = freq_response(res.K_z, f)
    fig, ax = rep.figure("controller", f"Fig. 5: K(z) of order {res.order} (solid) and the "
                         f"full K(s) of order {res.order_full} (dashed), V/µm",
                         nrows=2, sharex=True)
    for i in range(2):
        for j in range(2):
            line, = ax[0].loglog(f, np.abs(Kz[:, i, j]), label=f"K[{i},{j}]")
            ax[0].loglog(f, np.abs(Kf[:, i, j]), "--", color=line.get_color(), lw=0.8)
            ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(Kz[:, i, j]))),
                           color=line.get_color())
    ax[0].set_ylabel("|K| (V/µm)")
    ax[1].set_ylabel("phase (deg)")
    ax[1].set_xlabel("frequency (Hz)")
    ax[0].legend(ncol=4)
    for a in ax:
        a.grid(True, which="both", alpha=0.3)


def design_report(out, cfg, res, rob=None, title="rigd design") -> Report:
    rep = Report(out, title)
    rep.heading("Design")
    rep.table(["gamma", "full order", "order", "band error"],
              [[f"{res.gamma:.3f}", res.order_full, res.order, f"{res.band_error:.3f}"]])
    fig_weights(rep, cfg)
    if rob is not None:
        s = rob.summary()
        rep.table(["realizations", "all stable", "min in-band reduction", "peak |S_o|",
                   "peak at (Hz)", "low-frequency increase"],
                  [[s["n_realizations"], s["all_stable"], f"{s['sensitivity_reduction_min']:.2f}",
                    f"{s['sensitivity_peak_max']:.2f}", f"{s['sensitivity_peak_hz']:.0f}",
                    f"{s['sensitivity_low_increase_max']:.2f}"]])
        fig_sensitivity(rep, rob)
    fig_controller(rep, res)
    rep.write()
    return rep


def fig_impact(rep: Report, name: str, caption: str, runs: list[tuple[str, object, dict]],
               axis: str) -> None:
    """Figs. 6–7: displacement, valve commands and force of impacts, K∞ off and on.

    ``runs``: list of (label, Record, fit dict of that axis).
    """
    fig, ax = rep.figure(name, caption, nrows=3, sharex=True)
    for label, rec, fit in runs:
        c = rec.columns
        t = c["t"] - fit.get("t_impact_s", 0.0) + 0.01
        ax[0].plot(t, c[f"e_{axis}"] - np.median(c[f"e_{axis}"][:20]),
                   label=f"{label}: zeta={fit['zeta']:.3f}±{fit['zeta_std']:.3f}")
        ax[1].plot(t, c[f"r_{axis}"], label=label)
        ax[2].plot(t, c[f"f_{axis}"], label=label)
    ax[0].set_ylabel(f"e_{axis} (µm)")
    ax[1].set_ylabel(f"r_{axis} (V)")
    ax[2].set_ylabel(f"f_{axis} (N)")
    ax[2].set_xlabel("time (s), impact at 0.01 s")
    ax[0].set_xlim(0, 0.1)
    for a in ax:
        a.legend(fontsize=8)
        a.grid(True, alpha=0.3)
