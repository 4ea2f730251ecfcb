"""Configuration of the simulated plant: the ``plant:`` section of ``config/sim.yaml``.

Every hidden effect is off by default; switching one on (``enabled: true``) uses the default
strength documented in ``docs/plant.md`` unless its keys are given.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from rigd.configio import StrictModel

Pair = Annotated[list[float], Field(min_length=2, max_length=2)]


class Noise(StrictModel):
    """Sensor noise, Gaussian, standard deviations."""

    e_um: float = Field(0.03, ge=0.0, le=5.0, description="eddy-current sensors e_x, e_y, µm")
    y_p_v: float = Field(0.003, ge=0.0, le=1.0, description="valve position sensors, V")


class Valves(StrictModel):
    """Piezo valves (true parameters in ``rigd_drivers.plant.physics.VALVE_*``)."""

    f_scale: float = Field(1.0, gt=0.25, le=4.0, description="scales every valve's frequencies")
    initial_drive_v: float = Field(5.0, ge=0.0, le=10.0,
                                   description="the plant starts at rest under this drive, V")


class Delay(StrictModel):
    """Transport delay valve position → film force (effect ``delay``)."""

    enabled: bool = False
    samples: int = Field(3, ge=1, le=63, description="delay in loop periods")


class CubicStiffness(StrictModel):
    """Film stiffening ``f = −k3·|p|²·p`` at large eccentricity (effect ``cubic_stiffness``)."""

    enabled: bool = False
    ratio_at_gap: float = Field(2.0, gt=0.0, le=20.0,
                                description="k3·gap²/k: added stiffness at |p| = 25 µm, relative")


class ExtraMode(StrictModel):
    """An additional structural mode seen at the sensors (effect ``extra_mode``).

    Modal coordinate q (µm): ``q̈ + 2ζω q̇ + ω² q = ω² (b_x u_x + b_y u_y)``;
    ``e_x += c_x q``, ``e_y += c_y q``.
    """

    enabled: bool = False
    f_hz: float = Field(240.0, ge=20.0, le=2000.0)
    zeta: float = Field(0.02, gt=0.0, le=1.0)
    input_um_per_v: Pair = Field(default_factory=lambda: [0.04, 0.025],
                                 description="b_x, b_y: static q per V of u_x, u_y")
    output: Pair = Field(default_factory=lambda: [1.0, 0.6], description="c_x, c_y")


class Hysteresis(StrictModel):
    """Piezo hysteresis per valve: Bouc–Wen operator (n = 1, β = γ) on the drive voltage.

    ``v_h = v − h`` with ``dh = α dv − β|dv| h − β dv |h|``, solved exactly per step;
    h saturates at ±``h_max_v``.
    """

    enabled: bool = False
    h_max_v: float = Field(0.5, gt=0.0, le=3.0, description="half-width of the loop, V")
    alpha: float = Field(0.5, gt=0.0, lt=1.0, description="dh/dv right after a reversal")


class Creep(StrictModel):
    """Slow piezo creep: two first-order lags adding fractions of the drive (effect ``creep``)."""

    enabled: bool = False
    fraction: Pair = Field(default_factory=lambda: [0.08, 0.10])
    tau_s: Pair = Field(default_factory=lambda: [0.05, 0.5])


class Runout(StrictModel):
    """Surface run-out (sensor harmonics k = 1, 2 of phi) and mass unbalance (effect ``runout``)."""

    enabled: bool = False
    x_um: Pair = Field(default_factory=lambda: [0.8, 0.3], description="1×, 2× amplitude on e_x")
    x_phase_deg: Pair = Field(default_factory=lambda: [20.0, 75.0])
    y_um: Pair = Field(default_factory=lambda: [0.7, 0.25])
    y_phase_deg: Pair = Field(default_factory=lambda: [110.0, -30.0])
    unbalance_g_mm: float = Field(4.0, ge=0.0, le=1000.0, description="m·e of the unbalance")
    unbalance_phase_deg: float = 0.0


class Effects(StrictModel):
    """Hidden effects, each off by default (canonical names of docs/ARCHITECTURE.md)."""

    delay: Delay = Field(default_factory=Delay)
    cubic_stiffness: CubicStiffness = Field(default_factory=CubicStiffness)
    extra_mode: ExtraMode = Field(default_factory=ExtraMode)
    hysteresis: Hysteresis = Field(default_factory=Hysteresis)
    creep: Creep = Field(default_factory=Creep)
    runout: Runout = Field(default_factory=Runout)

    def enabled(self) -> list[str]:
        """Names of the effects switched on."""
        return [n for n in type(self).model_fields if getattr(self, n).enabled]


class PlantOptions(StrictModel):
    """The ``plant:`` section of the sim config."""

    seed: int = Field(1, ge=0, le=2**53 - 1, description="noise seed")
    omega_rpm: float = Field(0.0, ge=0.0, le=6000.0, description="shaft speed Ω, rpm")
    p_inj_bar: float = Field(4.0, ge=3.0, le=7.0, description="injection pressure P_I, bar")
    substeps: int = Field(4, ge=1, le=64,
                          description="sub-steps per period for the nonlinear film force")
    noise: Noise = Field(default_factory=Noise)
    valves: Valves = Field(default_factory=Valves)
    effects: Effects = Field(default_factory=Effects)
