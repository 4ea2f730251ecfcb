"""Design configuration (``config/design.yaml``) and the mixed-sensitivity weights.

The H∞ design of the paper (Sec. 5) bounds the stacked transfer N = [W_p S, W_u K∞ S]^T with
S = S_o = (I + G_p K∞)⁻¹ (Eq. 11): ‖N‖∞ < 1 means |S(jω)| < 1/|W_p(jω)| and
|K∞ S(jω)| < 1/|W_u(jω)| at every frequency.

* W_p (performance weight on S) is large inside the damping band (70–190 Hz in the paper,
  Fig. 3) and below 1 outside it: small S in the band, a bounded increase elsewhere
  (``1/low`` at low frequency, ``1/high`` above the band).
* W_u (control weight on K∞ S) is large at low frequency ("no action at low frequency": the
  controller must not fight the equilibrium moving with the operating point), small in the
  band and large again at high frequency (roll-off before the valve bandwidth and Nyquist).
* W_d (optional, not in the paper's N) weights a disturbance entering at the plant input
  (force-like, as an impact). Without it an S/KS design may cancel the lightly damped bearing
  poles with controller zeros, which leaves impact responses as poorly damped as before; with
  it the controller has to move the poles. ``W_d = 0`` gives the paper's plain N.

Each weight is the same diagonal three-level shape (:func:`three_level`): a minimum-phase
product of two shelving filters with real poles and zeros (well conditioned for the Riccati
solvers).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field, model_validator

from rigd.configio import StrictModel, load_model

TWO_PI = 2.0 * np.pi


class ThreeLevel(StrictModel):
    """|W(jω)| ≈ ``low`` below ``f_low_hz``, ``mid`` between ``f_low_hz`` and ``f_high_hz``,
    ``high`` above ``f_high_hz``; ``order`` = steepness (poles per transition)."""

    low: float = Field(gt=0)
    mid: float = Field(gt=0)
    high: float = Field(gt=0)
    f_low_hz: float = Field(gt=0)
    f_high_hz: float = Field(gt=0)
    order: int = Field(1, ge=1, le=4)

    @model_validator(mode="after")
    def _band(self):
        if not self.f_low_hz < self.f_high_hz:
            raise ValueError(f"f_low_hz ({self.f_low_hz:g}) must be below f_high_hz "
                             f"({self.f_high_hz:g})")
        return self


class Weights(StrictModel):
    """The three design weights (see module docstring)."""

    W_p: ThreeLevel
    W_u: ThreeLevel
    W_d: float = Field(0.0, ge=0, description="input-disturbance weight (0 = paper's N)")


class PlantSpec(StrictModel):
    """Design operating point (the model file's own when a model file is given)."""

    omega_rpm: float = Field(4000.0, ge=0)
    p_inj_bar: float = Field(7.0, gt=0)


class HighPass(StrictModel):
    """Plant augmentation H_hp(s) = (s/(s + ω_h))^m on each input, ω_h = 2π·``f_hz``.

    K̃ is designed on G_p·H_hp and K∞ = H_hp·K̃ is deployed, so K∞ has an m-fold zero at
    s = 0 (z = 1 after Tustin): the controller is inactive at DC and low frequency by
    construction (paper Sec. 5, Fig. 5). ``order: 0`` switches it off.
    """

    f_hz: float = Field(20.0, gt=0, description="corner frequency (Hz)")
    order: int = Field(2, ge=0, le=4, description="m: zeros at s = 0")


class Reduction(StrictModel):
    order: int = Field(4, ge=1, le=64)
    method: str = Field("truncate", pattern="^(truncate|matchdc)$")


class Structured(StrictModel):
    """Fixed-order multi-model tuning (:mod:`rigd.design.structured`)."""

    n_random_starts: int = Field(6, ge=0, le=64)
    n_samples: int = Field(8, ge=0, le=200, description="random operating points in the "
                           "design set, besides the design model and the range's corners")
    seed: int = Field(7, description="random starts and design-set samples (keep it apart "
                      "from robustness.seed: the assessment points are not design points)")
    peak_s_max: float | None = Field(1.9, gt=1.0, description="hard bound on σ̄(S_o) at "
                                     "every model of the set and frequency (a penalty beside "
                                     "γ, as systune's hard goals); null: only the weights bound "
                                     "it (by γ/|W_p|)")
    screen_iters: int = Field(25, ge=1, le=1000)
    n_polished: int = Field(3, ge=1, le=64, description="best screened starts polished")
    polish_iters: int = Field(200, ge=1, le=1000, description="cap per smoothing stage; a "
                              "stage ends when 4 iterations gain < 1e-5 (relative) — 40 "
                              "stopped before that, and γ then moved with rounding-level "
                              "changes of the data")


class Discretization(StrictModel):
    method: str = Field("tustin", pattern="^(tustin)$")
    prewarp_hz: float | None = Field(None, gt=0)


class Robustness(StrictModel):
    n_realizations: int = Field(30, ge=1, le=1000)
    seed: int = 1
    band_hz: tuple[float, float] = (70.0, 190.0)
    omega_rpm: tuple[float, float] = (0.0, 6000.0)
    p_inj_bar: tuple[float, float] = (3.0, 7.0)
    low_hz: float = Field(20.0, gt=0, description="'low frequency' is below this")

    @model_validator(mode="after")
    def _ranges(self):
        for name in ("band_hz", "omega_rpm", "p_inj_bar"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ValueError(f"{name}: lower bound {lo:g} above upper bound {hi:g}")
        return self


class DesignConfig(StrictModel):
    """``config/design.yaml``: everything ``rigd design`` needs besides the model."""

    rigd_design: int = Field(1, ge=1, le=1)
    fs_hz: float = Field(5000.0, gt=0)
    design_point: PlantSpec = PlantSpec()
    weights: Weights
    highpass: HighPass = HighPass(order=0)
    method: str = Field("structured", pattern="^(structured|truncate)$",
                        description="structured: fixed-order multi-model tuning of "
                        "reduction.order states; truncate: balanced truncation of the "
                        "full-order H∞ controller")
    reduction: Reduction = Reduction()
    structured: Structured = Structured()
    discretization: Discretization = Discretization()
    robustness: Robustness = Robustness()


def load_design_config(path: str | Path) -> DesignConfig:
    """Read and validate a design YAML (InputError with file:line on any problem)."""
    return load_model(path, DesignConfig)


# --- maths -------------------------------------------------------------------------------
def _shelf(r: float, edge_w: float, order: int, side: str) -> tuple[np.ndarray, np.ndarray]:
    """Polynomials (num, den) of ((s/ωz + 1)/(s/ωp + 1))^order with high-frequency gain r.

    ``side='low'``: the transition *ends* at ``edge_w``; ``side='high'``: it *starts* there.
    """
    k = r ** (1.0 / order)
    if side == "low":
        wp, wz = (edge_w, edge_w / k) if k >= 1 else (edge_w * k, edge_w)
    else:
        wp, wz = (edge_w * k, edge_w) if k >= 1 else (edge_w, edge_w / k)
    num = np.array([1.0])
    den = np.array([1.0])
    for _ in range(order):
        num = np.polymul(num, [1.0 / wz, 1.0])
        den = np.polymul(den, [1.0 / wp, 1.0])
    return num, den


def three_level_tf(w: ThreeLevel) -> tuple[np.ndarray, np.ndarray]:
    """SISO (num, den) in s (rad/s) of a :class:`ThreeLevel` weight."""
    n1, d1 = _shelf(w.mid / w.low, TWO_PI * w.f_low_hz, w.order, "low")
    n2, d2 = _shelf(w.high / w.mid, TWO_PI * w.f_high_hz, w.order, "high")
    return w.low * np.polymul(n1, n2), np.polymul(d1, d2)


def three_level(w: ThreeLevel, n: int = 2):
    """Diagonal n×n python-control ``StateSpace`` with :func:`three_level_tf` on each channel."""
    import control

    num, den = three_level_tf(w)
    h = control.ss(control.tf(num, den))
    return control.append(*([h] * n))


def highpass_ss(hp: HighPass, n: int = 2):
    """Diagonal n×n ``StateSpace`` H_hp(s) = (s/(s + ω_h))^m (identity when m = 0)."""
    import control

    if hp.order == 0:
        return control.ss([], [], [], np.eye(n))
    h = control.ss(control.tf([1.0, 0.0], [1.0, TWO_PI * hp.f_hz]) ** hp.order)
    return control.append(*([h] * n))


def magnitude(w: ThreeLevel, f_hz: np.ndarray) -> np.ndarray:
    """|W(j2πf)| of a weight (for plots and checks)."""
    num, den = three_level_tf(w)
    s = 1j * TWO_PI * np.asarray(f_hz, dtype=float)
    return np.abs(np.polyval(num, s) / np.polyval(den, s))
