"""The structured design route of :func:`rigd.design.pipeline.design`: the design set, the
starts, the tuning, the checks.

The design set is the design model G_p, the four corners of the operating range
(``robustness.omega_rpm`` × ``robustness.p_inj_bar``) and ``structured.n_samples`` random
operating points (seed ``structured.seed``, not the assessment's ``robustness.seed``) of
``plant_at(Ω, P_I)`` (the reassembled G_bear × actuator). Starts: the balanced truncation
of the full-order H∞ controller to n states projected on the structure, and
``structured.n_random_starts`` seeded random controllers.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from rigd.design import discretize, structured
from rigd.design.fixed_order import FixedOrder
from rigd.design.robustness import default_freqs, is_stable, random_operating_points
from rigd.design.weights import DesignConfig, magnitude
from rigd.errors import InputError


def design_set(G, cfg: DesignConfig, plant_at: Callable | None = None) -> list[tuple[str, object]]:
    """[(label, continuous G_p)] of the structured tuning (see module docstring)."""
    out = [("design model", G)]
    if plant_at is None:
        return out
    r = cfg.robustness
    corners = [(om, p) for om in r.omega_rpm for p in r.p_inj_bar]
    pts = corners + [tuple(v) for v in random_operating_points(
        cfg.structured.n_samples, cfg.structured.seed, r.omega_rpm, r.p_inj_bar)]
    seen = set()
    for om, p in pts:
        if (om, p) in seen:
            continue
        seen.add((om, p))
        out.append((f"Ω={om:.0f} rpm, P_I={p:.2f} bar", plant_at(float(om), float(p))))
    return out


def tuning_grid(fs_hz: float, band_hz) -> np.ndarray:
    """Frequency grid of the tuning (Hz): log-spaced 1 Hz … 0.48·fs, 2 Hz steps from
    below the band to twice its top (the resonances and the S_o peak)."""
    lo, hi = 0.7 * band_hz[0], 2.1 * band_hz[1]
    return np.unique(np.r_[np.logspace(0, np.log10(0.48 * fs_hz), 120),
                           np.linspace(lo, hi, int((hi - lo) / 2) + 1)])


def problem(models, cfg: DesignConfig, structure: FixedOrder, f_hz) -> structured.Problem:
    fs = cfg.fs_hz
    dms = [structured.discretize_model(Gi, fs, f_hz, lab) for lab, Gi in models]
    return structured.Problem(structure, dms, np.asarray(f_hz), fs, cfg.discretization.prewarp_hz,
                              magnitude(cfg.weights.W_p, f_hz), magnitude(cfg.weights.W_u, f_hz),
                              cfg.weights.W_d, s_max=cfg.structured.peak_s_max)


def tune_structured(G, cfg: DesignConfig, K_full, order: int,
                    plant_at: Callable | None = None) -> dict:
    """Tune a K∞ of ``order`` states on the design set; returns its pieces.

    Returns
    -------
    dict
        ``K`` (continuous, rad/s), ``K_z`` (Tustin), ``gamma`` (max over the set on the dense
        grid), ``design_set`` ([{label, gamma, rho, stable}]), ``tuning`` (starts, time).

    Raises
    ------
    InputError
        One line when the structure cannot hold the DC zeros or stabilise the whole set.
    """
    from rigd.design import reduce

    m = cfg.highpass.order
    fo = FixedOrder(order, m)
    why = fo.feasible()
    if why:
        raise InputError(f"--order {order}: {why}", "design")
    models = design_set(G, cfg, plant_at)
    t0 = time.perf_counter()
    prob = problem(models, cfg, fo, tuning_grid(cfg.fs_hz, cfg.robustness.band_hz))
    sc = cfg.structured
    rng = np.random.default_rng(sc.seed)
    starts = [structured.project(fo, reduce.reduce_controller(K_full, order), rng)]
    starts += [structured.random_start(fo, rng) for _ in range(sc.n_random_starts)]
    res = structured.tune(prob, starts, screen_iters=sc.screen_iters,
                          polish=((30.0, sc.polish_iters), (100.0, sc.polish_iters),
                                  (300.0, sc.polish_iters)), keep=sc.n_polished)
    t_tune = time.perf_counter() - t0
    K = fo.ss(res.x)
    Kz = discretize.tustin(K, cfg.fs_hz, cfg.discretization.prewarp_hz)
    dense = problem(models, cfg, fo, default_freqs(cfg.fs_hz))
    sig = dense.sigma(res.x)
    rho = dense.spectral_radius(res.x)
    rows = []
    for (lab, Gi), g, r in zip(models, sig.max(axis=1), rho):
        st = is_stable(discretize.zoh(Gi, cfg.fs_hz), Kz)   # independent check (python-control)
        rows.append({"label": lab, "gamma": float(g), "rho": float(r), "stable": st})
    bad = [r["label"] for r in rows if not r["stable"]]
    if bad:
        raise InputError(f"the tuned {order}-state controller leaves {len(bad)} model(s) of the "
                         f"design set unstable ({bad[0]}, ...)", "design")
    return {"K": K, "K_z": Kz, "gamma": float(sig.max()), "design_set": rows,
            "tuning": {"order": order, "dc_zeros": m, "strictly_proper": fo.strictly_proper,
                       "n_models": len(models), "n_freqs": len(prob.f_hz),
                       "gamma_grid": res.gamma, "starts": res.starts,
                       "peak_s_max": cfg.structured.peak_s_max,
                       "peak_s_design_set": dense.peak_s(res.x),
                       "n_evaluations": res.n_evals, "time_s": t_tune}}


def gamma_on_set(G, cfg: DesignConfig, Kz, plant_at: Callable | None = None) -> list[dict]:
    """[{label, gamma}] of any discrete K∞(z) on the design set (dense grid): the same
    measure the structured tuning minimises, for a side-by-side."""
    from rigd.design.robustness import freq_response

    f = default_freqs(cfg.fs_hz)
    models = design_set(G, cfg, plant_at)
    prob = problem(models, cfg, FixedOrder(2, 0), f)
    sig = prob.sigma_of(freq_response(Kz, f))
    return [{"label": lab, "gamma": float(g)} for (lab, _G), g in zip(models, sig.max(axis=1))]
