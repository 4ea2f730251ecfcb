"""The whole design chain: H∞ synthesis → fixed-order tuning or balanced reduction → Tustin
→ checks → file.

:func:`design` picks the method (``DesignConfig.method``):

* ``structured`` (default, :func:`design_structured`): the full-order H∞ controller is
  synthesised (γ of the full order, and the start), then a K∞ of ``reduction.order`` states
  with its zeros at DC built in is tuned on a *set* of plant models — the design model, the
  four corners of the operating range and ``structured.n_samples`` random operating points
  of ``plant_at`` — for the worst-case ‖F_l(P_i, K)‖∞ under closed-loop stability at every
  model (:mod:`rigd.design.structured`);
* ``truncate`` (:func:`design_controller`), the paper's route:

1. full-order K∞(s) by mixed-sensitivity H∞ (:mod:`rigd.design.hinf`), γ reported; with a
   high-pass (``highpass.order`` m > 0) K∞ = H_hp·K̃;
2. balanced truncation to ``reduction.order`` states (:mod:`rigd.design.reduce`) — with a
   high-pass, K̃ is truncated to ``order − 2m`` states and H_hp is re-applied, so the reduced
   K∞ keeps its exact zeros at DC (truncating K∞ itself would not); when the
   reduced controller does not stabilise the design model, or its frequency response leaves
   the full one by more than ``reduction.max_band_error`` inside the damping band, the order
   is raised two states at a time (up to the full order) and the order used is reported;
3. Tustin discretisation at the loop rate (:mod:`rigd.design.discretize`);
4. closed-loop stability with the full, the reduced and the discrete controller (the
   discrete one against the ZOH-discretised model).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.design import discretize, hinf, reduce
from rigd.design.robustness import freq_response, is_stable
from rigd.design.weights import DesignConfig
from rigd.errors import InputError


@dataclass
class DesignResult:
    K_full: Any              # continuous full-order K∞(s)
    K_red: Any               # continuous reduced K∞(s)
    K_z: Any                 # discrete reduced K∞(z) at fs
    gamma: float
    order_full: int
    order_requested: int
    order: int
    stable_full: bool
    stable_reduced: bool
    stable_discrete: bool
    band_error: float        # max over the band of σ̄(K_z − K_full)/σ̄(K_full)
    fs_hz: float
    tried: list[dict] = field(default_factory=list)
    hsv: list = field(default_factory=list)   # Hankel singular values of the reduced part
    highpass: dict | None = None
    lowfreq_gain_ratio: float = float("nan")  # σ̄(K_z) at 1 Hz / max in band
    method: str = "truncate"
    gamma_full: float = float("nan")          # γ of the full-order H∞ controller
    design_set: list = field(default_factory=list)   # [{label, gamma, rho}] (structured)
    tuning: dict = field(default_factory=dict)       # starts, evaluations, time
    comparison_failed: str | None = None             # why the side-by-side design failed
    conditioning: dict = field(default_factory=dict)  # what the synthesis model dropped
    gamma_full_optimal: float = float("nan")  # optimal γ (gamma_full if not relaxed)
    relaxed: list = field(default_factory=list)   # relaxed levels tried for a stable K̃

    def summary(self) -> dict:
        out = {} if self.comparison_failed is None else {
            "comparison_failed": self.comparison_failed}
        return {**out, "method": self.method, "gamma": self.gamma,
                "gamma_full_order": self.gamma_full,
                "gamma_full_order_optimal": self.gamma_full_optimal,
                "full_order_relaxed": self.relaxed,
                "order_full": self.order_full, "design_set": self.design_set,
                "tuning": self.tuning, "synthesis_model": self.conditioning,
                "order_requested": self.order_requested, "controller_order": self.order,
                "closed_loop_stable": {"full": self.stable_full, "reduced": self.stable_reduced,
                                       "discrete": self.stable_discrete},
                "band_error": self.band_error, "fs_hz": self.fs_hz,
                "highpass": self.highpass,
                "controller_gain_1hz_over_band_max": self.lowfreq_gain_ratio,
                "hankel_singular_values": self.hsv,
                "reduction_tries": self.tried}


def band_error(K_ref, K_test, band_hz, n: int = 200) -> float:
    """max over the band of σ̄(K_test − K_ref) / σ̄(K_ref) (continuous or discrete each)."""
    f = np.linspace(band_hz[0], band_hz[1], n)
    R = freq_response(K_ref, f)
    T = freq_response(K_test, f)
    num = np.linalg.svd(T - R, compute_uv=False)[:, 0]
    den = np.linalg.svd(R, compute_uv=False)[:, 0]
    return float(np.max(num / np.maximum(den, 1e-300)))


def _synthesize(G, cfg: DesignConfig):
    """Full-order H∞ on ``G`` conditioned for the synthesis (:mod:`rigd.design.condition`:
    poles far above the loop rate residualised, non-minimal states removed; what was done
    in ``syn.conditioning``), its closed loop checked on ``G`` itself."""
    from rigd.design.condition import condition

    if G.dt:
        raise InputError("the design model must be continuous (G_p(s))", "model")
    Gc, info = condition(G, cfg.fs_hz)
    syn = hinf.synthesize(Gc, cfg.weights, cfg.highpass)
    syn.conditioning = info
    syn.closed_loop_stable = is_stable(G, syn.K)
    if not syn.closed_loop_stable:
        raise InputError(f"H∞ controller does not stabilise the design model (γ = "
                         f"{syn.gamma:.3g}); check the weights", "design")
    return syn


def design(G, cfg: DesignConfig, *, method: str | None = None, order: int | None = None,
           plant_at=None, compare: bool = True) -> tuple[DesignResult, DesignResult | None]:
    """The design by ``method`` (default ``cfg.method``) with ``order`` states (default
    ``cfg.reduction.order``), and — for ``structured`` with ``compare`` — the truncated
    full-order design for a side-by-side (None when truncation finds no order).

    ``plant_at(Ω rpm, P_I bar) -> G_p(s)`` gives the operating-range models of the
    structured design set (without it the set is the design model alone).
    """
    method = method or cfg.method
    if order is not None:
        cfg = cfg.model_copy(update={"reduction": cfg.reduction.model_copy(
            update={"order": int(order)})})
    syn = _synthesize(G, cfg)
    if method == "truncate":
        return design_controller(G, cfg, syn=syn), None
    res = design_structured(G, cfg, syn=syn, plant_at=plant_at)
    cmp = None
    if compare:
        try:
            cmp = design_controller(G, cfg, syn=syn)
        except InputError as exc:
            res.comparison_failed = f"truncate: {exc.message}"
    return res, cmp


def design_structured(G, cfg: DesignConfig, *, syn=None, plant_at=None) -> DesignResult:
    """Fixed-order multi-model H∞ tuning (:mod:`rigd.design.structured_design`)."""
    from rigd.design.structured_design import tune_structured

    syn = syn or _synthesize(G, cfg)
    order = cfg.reduction.order
    t = tune_structured(G, cfg, syn.K, order, plant_at)
    Kr, Kz = t["K"], t["K_z"]
    fs, band = cfg.fs_hz, cfg.robustness.band_hz
    f_band = np.linspace(band[0], band[1], 121)
    k_band = np.linalg.svd(freq_response(Kz, f_band), compute_uv=False)[:, 0].max()
    k_1hz = np.linalg.svd(freq_response(Kz, np.array([1.0])), compute_uv=False)[0, 0]
    hp = cfg.highpass
    return DesignResult(K_full=syn.K, K_red=Kr, K_z=Kz, gamma=t["gamma"],
                        order_full=syn.K.nstates, order_requested=order, order=Kz.nstates,
                        stable_full=syn.closed_loop_stable, stable_reduced=is_stable(G, Kr),
                        stable_discrete=is_stable(discretize.zoh(G, fs), Kz),
                        band_error=band_error(syn.K, Kz, band), fs_hz=fs,
                        hsv=[float(v) for v in reduce.hankel_singular_values(syn.K_tilde)],
                        highpass=hp.model_dump() if hp.order else None,
                        lowfreq_gain_ratio=float(k_1hz / k_band), method="structured",
                        gamma_full=syn.gamma, design_set=t["design_set"], tuning=t["tuning"],
                        conditioning=syn.conditioning, gamma_full_optimal=syn.gamma_optimal,
                        relaxed=syn.relaxed)


def design_controller(G, cfg: DesignConfig, *, max_band_error: float = 0.1,
                      syn=None) -> DesignResult:
    """Truncation route on the continuous plant model ``G`` (r → p, 2×2)."""
    hp = cfg.highpass
    syn = syn or _synthesize(G, cfg)
    Kf = syn.K
    Kt = syn.K_tilde
    n_hp = Kf.nstates - Kt.nstates            # states of H_hp (2m), re-applied after reduction
    fs = cfg.fs_hz
    band = cfg.robustness.band_hz
    Gz = discretize.zoh(G, fs)
    tried = []
    order = min(max(cfg.reduction.order, n_hp + 2), Kf.nstates)
    chosen = None
    while True:
        Ktr = reduce.reduce_controller(Kt, order - n_hp, cfg.reduction.method)
        Kr = syn.H * Ktr if syn.H is not None else Ktr
        Kz = discretize.tustin(Kr, fs, cfg.discretization.prewarp_hz)
        st_r = is_stable(G, Kr)
        st_z = is_stable(Gz, Kz)
        kz_ok = bool(np.max(np.abs(np.linalg.eigvals(Kz.A)), initial=0.0) < 1.0)
        err = band_error(Kf, Kz, band)
        tried.append({"order": order, "stable_reduced": st_r, "stable_discrete": st_z,
                      "controller_stable": kz_ok, "band_error": err})
        if st_r and st_z and kz_ok and err <= max_band_error:
            chosen = (order, Kr, Kz, st_r, st_z, err)
            break
        if order >= Kf.nstates:
            break
        order = min(order + 2, Kf.nstates)
    if chosen is None:
        why = "; ".join(
            f"order {t['order']}: " + (", ".join(
                [n for k, n in (("stable_reduced", "closed loop K(s) unstable"),
                                ("stable_discrete", "closed loop K(z) unstable"),
                                ("controller_stable", "K(z) itself unstable")) if not t[k]]
                + ([f"band error {t['band_error']:.2g}"] if t["band_error"] > max_band_error
                   else [])) or "ok") for t in tried)
        raise InputError("no reduced controller (up to the full order "
                         f"{Kf.nstates}) is stable in closed loop and matches the full one "
                         f"within {max_band_error:.0%} in the band; tried: {why}", "design")
    order, Kr, Kz, st_r, st_z, err = chosen
    f_band = np.linspace(band[0], band[1], 121)
    k_band = np.linalg.svd(freq_response(Kz, f_band), compute_uv=False)[:, 0].max()
    k_1hz = np.linalg.svd(freq_response(Kz, np.array([1.0])), compute_uv=False)[0, 0]
    return DesignResult(K_full=Kf, K_red=Kr, K_z=Kz, gamma=syn.gamma, order_full=Kf.nstates,
                        order_requested=cfg.reduction.order, order=order,
                        stable_full=syn.closed_loop_stable, stable_reduced=st_r,
                        stable_discrete=st_z, band_error=err, fs_hz=fs, tried=tried,
                        hsv=[float(v) for v in reduce.hankel_singular_values(Kt)],
                        highpass=hp.model_dump() if hp.order else None,
                        lowfreq_gain_ratio=float(k_1hz / k_band), gamma_full=syn.gamma,
                        conditioning=syn.conditioning, gamma_full_optimal=syn.gamma_optimal,
                        relaxed=syn.relaxed)


def save_design(path, result: DesignResult, cfg: DesignConfig, *, model_hash: str | None = None,
                design_model=None, note: str | None = None) -> None:
    """Write the controller YAML (discrete K∞(z), continuous reduced K∞(s), weights, γ).

    With ``design_model`` (continuous G_p) its ZOH discretisation is embedded as
    ``design_plant`` and the closed loop is checked with it before writing; the loader
    re-checks it at every load.
    """
    from rigd.controller import save_controller

    Kz, Kr = result.K_z, result.K_red
    plant = dp = None
    if design_model is not None:
        plant = discretize.zoh(design_model, result.fs_hz)
        dp = {k: np.asarray(getattr(plant, k)).tolist() for k in "ABCD"}
    save_controller(path, Kz.A, Kz.B, Kz.C, Kz.D, fs_hz=result.fs_hz,
                    continuous={"A": np.asarray(Kr.A).tolist(), "B": np.asarray(Kr.B).tolist(),
                                "C": np.asarray(Kr.C).tolist(), "D": np.asarray(Kr.D).tolist()},
                    model_hash=model_hash, weights=cfg.weights.model_dump(),
                    closed_loop_stable=bool(result.stable_discrete), gamma=float(result.gamma),
                    note=note, design_plant=dp, plant=plant)
