"""Rig and simulation configuration (``config/sim.yaml``, ``config/rig.yaml``) as typed models.

Load with :func:`load_config`: the YAML is safe-loaded, validated into :class:`RigConfig`, and
the driver sections are validated against each driver class's own ``Options`` model, so every
problem is reported as one ``file:line: key.path: problem`` line (:class:`rigd.errors.InputError`).

Units: voltages V, displacements µm, times s, rates Hz, speeds rpm, pressures bar.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from rigd.bounded import MAX_CONFIG_BYTES
from rigd.configio import LoadedYaml, StrictModel, read_text, read_yaml, validate
from rigd.controller import MAX_GAIN_V_PER_UM, NOMINAL_PLANT
from rigd.errors import InputError
from rigd.frame import IN_NAMES

FILM_GAP_UM = 25.0  # the fluid-film gap of the paper's bearing (Sec. 2)


class LoopConfig(StrictModel):
    """The cycle: rate, Eq. 1 offset, drive range, K∞ blending."""

    fs_hz: float = Field(5000.0, gt=0, le=50000)        #: loop rate f_s, Hz
    r0_v: float = 5.0                                   #: r0 of Eq. 1, V
    drive_v: tuple[float, float] = (0.0, 10.0)          #: drive & valve reference range, V
    k_ramp_s: float = Field(0.05, ge=0, le=10)          #: K∞ enable/disable blend time, s
    #: p_eq tracking time constant while K∞ is off, s
    peq_tau_s: float = Field(0.2, gt=0, le=100)

    @model_validator(mode="after")
    def _ranges(self):
        lo, hi = self.drive_v
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError("drive_v must be [low, high] with low < high, got "
                             f"{list(self.drive_v)}")
        if not lo <= self.r0_v <= hi:
            raise ValueError(f"r0_v={self.r0_v} is outside drive_v {list(self.drive_v)}")
        return self


class ValvePD(StrictModel):
    """PD loop of one piezo valve: v = kff·r_p + kp·e + kd·d/dt_filtered(e), e = r_p - y_p."""

    kp: float = Field(1.5, ge=0, le=1000)               #: proportional gain, V/V
    kd: float = Field(1e-4, ge=0, le=10)                #: derivative gain, V·s/V
    tf_s: float = Field(1e-4, gt=0, le=1)               #: derivative filter time constant, s
    #: reference feed-forward gain, V/V (0: pure PD)
    kff: float = Field(1.0, ge=0, le=10)


class SupervisorConfig(StrictModel):
    """Limits checked every cycle (fault codes in rigd/loop/faults.py)."""

    enabled: bool = True
    e_range_um: tuple[float, float] = (-100.0, 100.0)   #: valid e_x/e_y sensor range, µm
    y_p_range_v: tuple[float, float] = (-0.5, 10.5)     #: valid y_p,i sensor range, V
    film_gap_um: float = Field(FILM_GAP_UM, gt=0)       #: bearing film gap, µm
    max_gap_fraction: float = Field(0.8, gt=0, le=2)    #: trip when |p - centre| > fraction·gap
    centre_um: tuple[float, float] = (0.0, 0.0)         #: bearing centre in sensor coordinates, µm
    stale_frames: int = Field(3, ge=0)                  #: repeated drv_seq tolerated (0: off)
    encoder_min_omega_rpm: float = Field(300.0, ge=0)   #: encoder check above this speed
    encoder_frozen_s: float = Field(0.01, ge=0)         #: phi frozen this long -> lost (0: off)
    valve_error_v: float = Field(3.0, gt=0)             #: valve tracking error limit, V
    valve_error_s: float = Field(0.05, ge=0)            #: ... tolerated this long (0: off)
    #: the plant's fastest closed-loop time constant, s (docs/loop.md "Liveness"); null: the
    #: fast driver's nominal plant model tells (the simulated plants), else 20 ms
    plant_tau_s: float | None = Field(None, gt=0, le=10)
    #: a gap between two cycles longer than this latches loop_stall, s (null: plant_tau_s;
    #: 0: off)
    stall_s: float | None = Field(None, ge=0, le=60)
    #: overrun storm: control time lost (gaps beyond one period, outputs held) in a leaky
    #: bucket of this time constant, s (null: 10 x plant_tau_s) ...
    overrun_storm_window_s: float | None = Field(None, gt=0, le=600)
    #: ... beyond this latches overrun_storm, s (null: the stall bound; 0: off)
    overrun_storm_lost_s: float | None = Field(None, ge=0, le=60)
    #: the former count rule (that many overruns within the window, whatever their size),
    #: used instead of the lost-time rule when set; null = the lost-time rule
    overrun_storm_count: int | None = Field(None, ge=1)
    slow_stale_s: float = Field(2.0, gt=0)              #: slow-driver data older -> fault
    #: bound for a slow driver's *first* good poll, counted from the loop's start (connect and
    #: first answer of a fresh device); the ``slow_stale_s`` clock starts at that poll
    slow_first_poll_s: float = Field(10.0, gt=0)

    @model_validator(mode="after")
    def _ranges(self):
        for name in ("e_range_um", "y_p_range_v"):
            lo, hi = getattr(self, name)
            if not lo < hi:
                raise ValueError(f"{name} must be [low, high] with low < high")
        return self


class RecorderConfig(StrictModel):
    """Ring buffer between the cycle and the HDF5 writer thread."""

    ring_frames: int = Field(1 << 18, ge=1024, le=1 << 26)   #: ring capacity, frames
    flush_interval_s: float = Field(0.5, gt=0, le=60)        #: HDF5 flush period, s
    chunk_frames: int = Field(4096, ge=64, le=1 << 20)       #: HDF5 chunk length, frames
    data_dir: str = "data"                                   #: default directory for recordings


class ClockConfig(StrictModel):
    """Which clock drives the cycle and how."""

    mode: Literal["realtime", "lockstep"] = "realtime"
    #: after a late cycle: skip missed periods or run them
    overrun: Literal["skip", "catch_up"] = "skip"
    priority: int = Field(80, ge=1, le=99)            #: SCHED_FIFO priority when permitted
    cpu: int | None = Field(None, ge=0)               #: pin the loop thread to this CPU
    #: busy-wait this long before each deadline, µs
    spin_us: float = Field(100.0, ge=0, le=5000)
    batch_cycles: int = Field(8192, ge=1, le=1 << 22)  #: lock-step cycles per compiled call


class DriverSpec(StrictModel):
    name: str = Field(min_length=1)                   #: entry-point name in group rigd.drivers
    options: dict[str, Any] = Field(default_factory=dict)


class SlowDriverSpec(DriverSpec):
    poll_hz: float = Field(20.0, gt=0, le=1000)


class DriversConfig(StrictModel):
    fast: DriverSpec = DriverSpec(name="sim")
    slow: list[SlowDriverSpec] = Field(default_factory=list)


class Calibration(StrictModel):
    """Engineering value = gain · driver value + offset (e.g. µm per V for e_x, e_y)."""

    gain: float = 1.0
    offset: float = 0.0

    @field_validator("gain")
    @classmethod
    def _gain(cls, v: float) -> float:
        if not math.isfinite(v) or v == 0.0:
            raise ValueError("gain must be a finite non-zero number")
        return v


CALIBRATABLE = ("e_x", "e_y", "y_p1", "y_p2", "y_p3", "y_p4", "f_x", "f_y")


class OperatingPoint(StrictModel):
    """Range check of ``set_operating_point`` (the paper's operating range)."""

    omega_rpm: float = Field(0.0, ge=0, le=6000)      #: Ω, rpm (paper range 0..6 krpm)
    p_inj_bar: float = Field(4.0, ge=3, le=7)         #: P_I, bar (paper range 3..7 bar)


class ControllerGatesConfig(StrictModel):
    """``controller_gates``: what a controller must pass before it reaches the loop, beyond
    the file checks (rate, shapes, finite, stable K∞): ``rigd ctl load``, the web upload and
    SIGHUP alike (docs/service.md, "Controller gates")."""

    max_gain_v_per_um: float = Field(MAX_GAIN_V_PER_UM, gt=0, allow_inf_nan=False,
                                     description="largest K∞ gain over frequency, V/µm")
    nominal_plant: str | None = Field(None, description="plant model file (A, B, C, D; fs_hz "
                                      "or continuous) the closed loop of a controller file "
                                      "without design_plant is checked on; relative to the "
                                      "config; default: rigd's nominal model of the rig")


class RigConfig(StrictModel):
    """The whole rig (or simulation) configuration."""

    loop: LoopConfig = LoopConfig()
    valves: list[ValvePD] = Field(default_factory=lambda: [ValvePD() for _ in range(4)])
    supervisor: SupervisorConfig = SupervisorConfig()
    recorder: RecorderConfig = RecorderConfig()
    clock: ClockConfig = ClockConfig()
    drivers: DriversConfig = DriversConfig()
    channels: dict[str, Calibration] = Field(default_factory=dict)
    controller: str | None = None                     #: K∞ controller file loaded at start
    controller_gates: ControllerGatesConfig = ControllerGatesConfig()
    plant: dict[str, Any] | None = None               #: options of the simulated plant (sim driver)

    @field_validator("valves")
    @classmethod
    def _four(cls, v: list[ValvePD]) -> list[ValvePD]:
        if len(v) != 4:
            raise ValueError(f"exactly 4 valves (PD loops) are needed, got {len(v)}")
        return v

    @field_validator("channels")
    @classmethod
    def _channels(cls, v: dict[str, Calibration]) -> dict[str, Calibration]:
        for name in v:
            if name not in CALIBRATABLE:
                raise ValueError(f"unknown channel {name!r} "
                                 f"(calibratable: {', '.join(CALIBRATABLE)})")
        return v

    def calibration_arrays(self):
        """(gains, offsets) float64[N_IN] for the input frame (identity where not given)."""
        import numpy as np

        g = np.ones(len(IN_NAMES))
        o = np.zeros(len(IN_NAMES))
        for name, cal in self.channels.items():
            i = IN_NAMES.index(name)
            g[i], o[i] = cal.gain, cal.offset
        return g, o


@dataclass
class LoadedConfig:
    """A validated config plus where it came from (for metadata and driver options)."""

    config: RigConfig
    path: str
    text: str
    yaml: LoadedYaml | None = None

    def gate_options(self) -> dict[str, Any]:
        """``controller_gates`` as plain values for another process: ``max_gain`` (V/µm) and
        ``nominal_plant`` (an absolute path; relative ones are taken from the config's
        folder)."""
        g = self.config.controller_gates
        plant = Path(g.nominal_plant) if g.nominal_plant else NOMINAL_PLANT
        if not plant.is_absolute():
            plant = Path(self.path).resolve().parent / plant
        return {"max_gain": g.max_gain_v_per_um, "nominal_plant": str(plant)}

    def driver_options(self, kind: str = "fast", index: int = 0):
        """Validated options of a driver: its ``Options`` model instance, or the raw dict."""
        return _driver_options(self, kind, index)


def _where(loaded: LoadedYaml | None, source: str, loc: tuple) -> str:
    from rigd.configio import _fmt_loc

    line = loaded.line_of(loc) if loaded is not None else None
    return f"{source}:{line}: {_fmt_loc(loc)}" if line else f"{source}: {_fmt_loc(loc)}"


def _options_section(cfg: RigConfig, kind: str, index: int) -> tuple[tuple, dict]:
    if kind == "fast":
        spec = cfg.drivers.fast
        if spec.name == "sim" and not spec.options and cfg.plant is not None:
            return ("plant",), cfg.plant
        return ("drivers", "fast", "options"), spec.options
    spec = cfg.drivers.slow[index]
    return ("drivers", "slow", index, "options"), spec.options


def _driver_options(lc: LoadedConfig, kind: str, index: int):
    from rigd.driver import driver_class

    cfg = lc.config
    spec = cfg.drivers.fast if kind == "fast" else cfg.drivers.slow[index]
    name_loc = ("drivers", "fast", "name") if kind == "fast" else ("drivers", "slow", index, "name")
    try:
        cls = driver_class(spec.name)
    except InputError as exc:
        raise InputError(exc.message, _where(lc.yaml, lc.path, name_loc)) from None
    if cls.kind != kind:
        raise InputError(f"driver {spec.name!r} is a {cls.kind} driver, not {kind}",
                         _where(lc.yaml, lc.path, name_loc))
    section, raw = _options_section(cfg, kind, index)
    model = getattr(cls, "Options", None)
    if model is None:
        return cls, raw
    if lc.yaml is not None and _has_section(lc.yaml.data, section):
        return cls, validate(lc.yaml, model, section=section)
    try:
        return cls, model.model_validate(raw)
    except Exception as exc:  # no YAML positions (config built in code)
        raise InputError(f"invalid driver options: {str(exc).splitlines()[0]}",
                         f"{lc.path}: {'.'.join(map(str, section))}") from None


def _has_section(data: Any, section: tuple) -> bool:
    for key in section:
        try:
            data = data[key]
        except (KeyError, IndexError, TypeError):
            return False
    return isinstance(data, dict)


def load_config(path: str | Path, *, text: str | None = None,
                check_drivers: bool = True) -> LoadedConfig:
    """Read, validate and cross-check a rig config file.

    Parameters
    ----------
    path : str or Path
        The YAML file (``config/sim.yaml``, ``config/rig.yaml``).
    text : str, optional
        YAML text attributed to ``path`` (tests).
    check_drivers : bool
        Also resolve every driver by name and validate its options section.

    Raises
    ------
    InputError
        ``file:line: key.path: problem`` for the first problem found.
    """
    path = str(path)
    if text is None:
        text = read_text(path, MAX_CONFIG_BYTES, "config file")
    loaded = read_yaml(path, text)
    if not isinstance(loaded.data, dict):
        raise InputError("a rig config must be a mapping of sections", path)
    cfg = validate(loaded, RigConfig)
    lc = LoadedConfig(cfg, path, text, loaded)
    if check_drivers:
        lc.driver_options("fast")
        for i in range(len(cfg.drivers.slow)):
            lc.driver_options("slow", i)
    if cfg.controller is not None:
        from rigd.controller import load_controller

        cpath = Path(cfg.controller)
        if not cpath.is_absolute():
            cpath = Path(path).parent / cpath
        try:
            load_controller(cpath, expected_fs_hz=cfg.loop.fs_hz)
        except InputError as exc:
            raise InputError(f"controller {cfg.controller!r}: {exc}",
                             _where(loaded, path, ("controller",))) from None
    return lc


def default_config(**sections: Any) -> LoadedConfig:
    """A config built in code (tests, ``simulate_record``): defaults plus ``sections``."""
    import yaml

    cfg = RigConfig.model_validate(sections)
    return LoadedConfig(cfg, "<default>", yaml.safe_dump(cfg.model_dump(mode="json"),
                                                         sort_keys=False))
