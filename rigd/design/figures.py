"""Design and impact figures (paper Figs. 3–7) on a :class:`rigd.htmlreport.Report`."""

from __future__ import annotations

import numpy as np

from rigd.design.robustness import freq_response
from rigd.design.weights import magnitude
from rigd.htmlreport import Report


def fig_weights(rep: Report, cfg) -> None:
    """Fig. 3: |W_p|, |W_u| and the bound 1/|W_p| on |S|."""
    f = np.logspace(0, np.log10(0.49 * cfg.fs_hz), 400)
    fig, ax = rep.figure("weights", "Fig. 3: weights W_p (on S) and W_u (on K S); 1/|W_p| is "
                         "the target bound on |S_o|")
    ax.loglog(f, magnitude(cfg.weights.W_p, f), label="|W_p|")
    ax.loglog(f, 1 / magnitude(cfg.weights.W_p, f), "--", label="1/|W_p|")
    ax.loglog(f, magnitude(cfg.weights.W_u, f), label="|W_u| (on K~)")
    if cfg.highpass.order:
        wh = cfg.highpass.f_hz
        ax.loglog(f, (f / np.hypot(f, wh)) ** cfg.highpass.order, ":",
                  label=f"|H_hp| ({cfg.highpass.order}x zero at DC, {wh:g} Hz)")
    ax.axvspan(*cfg.robustness.band_hz, color="0.9")
    ax.set_xlabel("frequency (Hz)")
    ax.legend(loc="upper right")
    ax.grid(True, which="both", alpha=0.3)


def fig_sensitivity(rep: Report, rob) -> None:
    """Fig. 4: σ̄(S_o) for every realization, its open-loop resonances marked."""
    sm = rob.summary()
    fig, ax = rep.figure("sensitivity", f"Fig. 4: max singular value of the output sensitivity "
                         f"S_o for {len(rob.realizations)} realizations of the operating range; "
                         f"band {rob.band_hz[0]:g}-{rob.band_hz[1]:g} Hz shaded; dots: each "
                         "realization's open-loop resonances")
    for s, r in zip(rob.sigma, rob.realizations):
        line, = ax.semilogx(rob.f_hz, 20 * np.log10(s), lw=0.7)
        if r.resonance_hz:
            ax.plot(r.resonance_hz, 20 * np.log10(np.interp(r.resonance_hz, rob.f_hz, s)), "o",
                    ms=3, color=line.get_color())
    ax.text(0.02, 0.04, "worst over realizations:\n"
            f"in-band reduction 1/max S_o: {sm['sensitivity_reduction_min']:.2f}\n"
            f"at own resonances (max sing. value): "
            f"{sm['sensitivity_reduction_at_resonance_min']:.2f}\n"
            f"at own resonances (mode direction): "
            f"{sm['sensitivity_reduction_at_resonance_mode_direction_min']:.2f}\n"
            f"max below {rob.low_hz:g} Hz: {sm['sensitivity_lowfreq_max']:.3f}; "
            f"peak {sm['sensitivity_peak_max']:.2f} at {sm['sensitivity_peak_hz']:.0f} Hz",
            transform=ax.transAxes, fontsize=7, va="bottom",
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    ax.axvspan(*rob.band_hz, color="0.9")
    ax.axhline(0, color="k", lw=0.8)
    ax.axhline(20 * np.log10(1 / 3), color="r", ls="--", lw=0.8, label="1/3")
    ax.axhline(20 * np.log10(2), color="r", ls=":", lw=0.8, label="2")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("max singular value of S_o (dB)")
    ax.legend(loc="lower right")
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
    ax[0].legend(ncol=4, loc="upper left")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)


def design_report(out, cfg, res, rob=None, title="rigd design", comparison=None,
                  comparison_failed: str | None = None) -> Report:
    rep = Report(out, title)
    rep.heading("Design")
    rep.table(["method", "gamma", "full order (gamma)", "order", "band error",
               "|K(1 Hz)| / max in band"],
              [[res.method, f"{res.gamma:.3f}", f"{res.order_full} ({res.gamma_full:.3f})",
                res.order, f"{res.band_error:.3f}", f"{res.lowfreq_gain_ratio:.4f}"]])
    if res.relaxed:
        rep.text(f"The full-order H∞ controller at the optimal γ {res.gamma_full_optimal:.3f} is "
                 "unstable by itself (its closed loop is stable): the central controller at "
                 f"γ {res.gamma_full:.3f} ({res.relaxed[-1]['factor']:g}× the optimum), the "
                 "first relaxed level at which it is stable, is used (docs/design.md).")
    if res.design_set:
        rep.table(["design-set model", "gamma", "closed-loop spectral radius", "stable"],
                  [[r["label"], f"{r['gamma']:.3f}", f"{r['rho']:.5f}", r["stable"]]
                   for r in res.design_set])
    if comparison_failed:
        rep.text(f"Side-by-side with the truncated full-order design: FAILED — "
                 f"{comparison_failed}")
    if comparison:
        keys = [("controller_order", "{}"), ("gamma", "{:.3f}"), ("all_stable", "{}"),
                ("sensitivity_peak_max", "{:.2f}"), ("sensitivity_lowfreq_max", "{:.3f}"),
                ("sensitivity_reduction_at_resonance_min", "{:.2f}"),
                ("sensitivity_reduction_at_resonance_mode_direction_min", "{:.2f}"),
                ("disturbance_peak_reduction_min", "{:.2f}")]
        names = list(comparison)
        rep.table(["quantity"] + names,
                  [[k] + [fmt.format(comparison[n][k]) if k in comparison[n] else "-"
                          for n in names] for k, fmt in keys])
    fig_weights(rep, cfg)
    if rob is not None:
        s = rob.summary()
        rep.table(["realizations", "all stable", "min in-band reduction",
                   "min reduction at resonance (sigma max / mode dir.)", "peak |S_o|",
                   "peak at (Hz)", "max |S_o| below low_hz"],
                  [[s["n_realizations"], s["all_stable"], f"{s['sensitivity_reduction_min']:.2f}",
                    f"{s['sensitivity_reduction_at_resonance_min']:.2f} / "
                    f"{s['sensitivity_reduction_at_resonance_mode_direction_min']:.2f}",
                    f"{s['sensitivity_peak_max']:.2f}", f"{s['sensitivity_peak_hz']:.0f}",
                    f"{s['sensitivity_lowfreq_max']:.3f}"]])
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
        a.legend(fontsize=8, loc="upper right")
        a.grid(True, alpha=0.3)
