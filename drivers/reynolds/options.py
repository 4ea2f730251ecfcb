"""Configuration of the physics-grade plant (driver ``sim_reynolds``): ``drivers.fast.options``.

Defaults are documented with their sources in docs/plant.md ("Physics-grade plant").
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rigd.configio import StrictModel
from rigd_drivers.sim.options import Noise, Valves


class Grid(StrictModel):
    """Finite-volume grid of the film (full bearing; the half length is solved)."""

    n_theta: int = Field(32, ge=8, le=128, description="cells around the circumference")
    n_z: int = Field(8, ge=2, le=32, description="cells along the bearing length (even)")

    @model_validator(mode="after")
    def _even(self):
        if self.n_z % 2:
            raise ValueError(f"grid.n_z must be even (the half length is solved; got {self.n_z})")
        return self


class Bearing(StrictModel):
    """Gas bearing and gas (SI units unless the name says otherwise)."""

    radius_mm: float = Field(15.0, gt=5.0, le=100.0, description="journal radius R")
    length_mm: float = Field(40.0, gt=5.0, le=200.0, description="bearing length L")
    clearance_um: float = Field(25.0, gt=5.0, le=100.0, description="radial clearance c")
    orifice_diameter_mm: float = Field(0.30, gt=0.05, le=3.0,
                                       description="injector orifice diameter (valve fully open)")
    discharge_coefficient: float = Field(0.8, gt=0.1, le=1.0)
    feed_half_width_deg: float = Field(12.0, gt=1.0, le=40.0,
                                       description="injection patch half-width around θ_i")
    feed_half_length_mm: float = Field(3.0, gt=0.2, le=50.0,
                                       description="injection patch half-length from the mid-plane")
    viscosity_pa_s: float = Field(1.81e-5, gt=0.0, le=1e-3, description="air at 20 °C")
    temperature_k: float = Field(293.15, gt=200.0, le=500.0)
    ambient_pa: float = Field(101325.0, gt=5e4, le=2e5)


class Feed(StrictModel):
    """Feed path of each injector: valve → chamber → feed hole → film (docs/plant.md)."""

    compensation: Literal["inherent", "orifice"] = Field(
        "orifice", description="feed-hole restriction: the curtain π d h (inherent) or the "
        "hole section π d²/4 (orifice)")
    hole_diameter_mm: float = Field(0.40, gt=0.05, le=3.0, description="feed hole diameter d")
    discharge_coefficient: float = Field(0.8, gt=0.1, le=1.0)
    chamber_volume_mm3: float = Field(1.0, ge=0.1, le=1e5,
                                      description="gas volume between valve seat and feed hole "
                                      "(tuned: the rig is free of pneumatic hammer)")


class Load(StrictModel):
    """Static load on the rotor: gravity (y vertical, +y up: valve 1 on top) and a constant
    force at the disc."""

    gravity_m_s2: float = Field(9.81, ge=0.0, le=20.0,
                                description="gravity along −y; 0: the weightless rig")
    disc_n: tuple[float, float] = Field((0.0, 0.0), description="constant force at the disc "
                                        "(x, y), N")

    @model_validator(mode="after")
    def _bounded(self):
        if max(abs(self.disc_n[0]), abs(self.disc_n[1])) > 500.0:
            raise ValueError(f"load.disc_n must be within ±500 N (got {list(self.disc_n)})")
        return self


class ReynoldsOptions(StrictModel):
    """Options of the ``sim_reynolds`` driver."""

    seed: int = Field(1, ge=0, le=2**53 - 1, description="noise seed")
    omega_rpm: float = Field(0.0, ge=0.0, le=6000.0, description="shaft speed Ω, rpm")
    p_inj_bar: float = Field(4.0, ge=3.0, le=7.0, description="injection pressure P_I, bar")
    supply_slew_bar_per_s: float = Field(
        10.0, ge=0.0, le=1e4, description="rate at which the supply pressure follows a new "
        "P_I (the regulator; 0: at once)")
    substeps: int = Field(4, ge=1, le=64, description="BDF2 sub-steps per loop period")
    newton_iterations: int = Field(1, ge=1, le=50,
                                   description="Newton iterations per sub-step, at least")
    newton_max_iterations: int = Field(8, ge=1, le=50,
                                       description="… at most, while the residual after the "
                                                   "update is above newton_tolerance")
    newton_tolerance: float = Field(1e-6, gt=0.0, le=1e-2,
                                    description="converged: the residual after the update asks "
                                                "for a pressure change below this fraction of "
                                                "p_a over the sub-step")
    grid: Grid = Field(default_factory=Grid)
    bearing: Bearing = Field(default_factory=Bearing)
    feed: Feed = Field(default_factory=Feed)
    load: Load = Field(default_factory=Load)
    modes: int = Field(4, ge=2, le=12, description="shaft modes kept per plane")
    unbalance_g_mm: float = Field(0.0, ge=0.0, le=1000.0, description="disc unbalance m·e")
    unbalance_phase_deg: float = 0.0
    noise: Noise = Field(default_factory=Noise)
    valves: Valves = Field(default_factory=Valves)

    @model_validator(mode="after")
    def _newton(self):
        if self.newton_max_iterations < self.newton_iterations:
            raise ValueError(f"newton_max_iterations ({self.newton_max_iterations}) must be at "
                             f"least newton_iterations ({self.newton_iterations})")
        return self
