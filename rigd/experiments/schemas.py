"""Experiment YAML schemas: one strict pydantic model per ``kind``.

A file holds one experiment; ``kind`` selects the schema (see docs/experiments.md)::

    kind: prbs | multilevel | multisine | chirp | runout | impact | sweep

Errors name the file, the line and the key (``exp.yaml:7: amplitude_v: Input should be greater
than 0 (got -1)``) through :mod:`rigd.configio`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from rigd.bounded import MAX_EXPERIMENT_BYTES
from rigd.configio import LoadedYaml, StrictModel, read_text, read_yaml, validate
from rigd.errors import InputError

#: longest one record (a segment: lead-in included) may last, s of loop time; checked before
#: anything runs (1 h of excitation plus the longest lead-in): a request beyond it would
#: allocate gigabytes for a record no rig session takes
MAX_RECORD_S = 4200.0

Axis = Literal["x", "y"]
Amplitude = float | list[float]


def _check_amplitude(v: Any) -> Any:
    vals = v if isinstance(v, list) else [v]
    if isinstance(v, list) and len(v) != 2:
        raise ValueError("give one amplitude or a pair [x, y]")
    for a in vals:
        if not (0.0 <= a <= 10.0):
            raise ValueError("amplitude must be within [0, 10] V")
    if max(vals) <= 0.0:
        raise ValueError("amplitude must be > 0 V on at least one axis")
    return v


class OperatingPoint(StrictModel):
    """Shaft speed Ω and injection pressure P_I (manometric) of a record."""

    omega_rpm: float = Field(ge=0.0, le=100000.0, allow_inf_nan=False)
    p_inj_bar: float = Field(ge=0.0, le=50.0, allow_inf_nan=False)


class _Base(StrictModel):
    name: str | None = Field(None, min_length=1, max_length=80, pattern=r"^[A-Za-z0-9_.\-]+$")
    description: str = ""
    operating_point: OperatingPoint | None = None


class _Excitation(_Base):
    """Fields shared by the excitation kinds (signals on r_x, r_y)."""

    amplitude_v: Amplitude
    axes: list[Axis] = Field(default_factory=lambda: ["x", "y"], min_length=1, max_length=2)
    lead_in_s: float = Field(0.5, ge=0.0, le=600.0, allow_inf_nan=False)
    controller: bool = False   #: K∞ enabled during the record

    @field_validator("amplitude_v")
    @classmethod
    def _amp(cls, v):
        return _check_amplitude(v)

    @field_validator("axes")
    @classmethod
    def _unique(cls, v):
        if len(set(v)) != len(v):
            raise ValueError("axes repeated")
        return v


class PrbsSpec(_Excitation):
    """PRBS identification record (the paper's excitation)."""

    kind: Literal["prbs"]
    duration_s: float = Field(gt=0.0, le=3600.0, allow_inf_nan=False)
    switch_probability: float = Field(0.5, gt=0.0, le=1.0)
    min_hold_s: float | None = Field(None, gt=0.0, le=60.0)
    seed: int = Field(0, ge=0)


class MultilevelSpec(_Excitation):
    """Random multi-level sequence (reveals amplitude-dependent effects)."""

    kind: Literal["multilevel"]
    duration_s: float = Field(gt=0.0, le=3600.0, allow_inf_nan=False)
    levels: int = Field(5, ge=3, le=64)
    switch_probability: float = Field(1.0, gt=0.0, le=1.0)
    min_hold_s: float | None = Field(None, gt=0.0, le=60.0)
    seed: int = Field(0, ge=0)


class MultisineSpec(_Excitation):
    """Periodic random-phase multisine on the grid k·fs/N."""

    kind: Literal["multisine"]
    f_min_hz: float = Field(gt=0.0, allow_inf_nan=False)
    f_max_hz: float = Field(gt=0.0, allow_inf_nan=False)
    period_s: float = Field(gt=0.0, le=600.0, allow_inf_nan=False)
    periods: int = Field(4, ge=1, le=10000)
    lines: Literal["all", "odd"] = "all"
    seed: int = Field(0, ge=0)

    @model_validator(mode="after")
    def _band(self):
        if self.f_max_hz <= self.f_min_hz:
            raise ValueError(f"f_max_hz ({self.f_max_hz}) must exceed f_min_hz "
                             f"({self.f_min_hz})")
        if self.f_min_hz * self.period_s < 0.999 and self.f_max_hz * self.period_s < 1.0:
            raise ValueError("no frequency line in the band: period_s too short for f_max_hz")
        if self.period_s * self.periods + self.lead_in_s > MAX_RECORD_S:
            raise ValueError(f"periods × period_s = {self.period_s * self.periods:g} s: over "
                             f"the limit of {MAX_RECORD_S:g} s per record (lead-in included)")
        return self

    @property
    def duration_s(self) -> float:
        return self.period_s * self.periods


class ChirpSpec(_Excitation):
    """Swept sine from f0_hz to f1_hz."""

    kind: Literal["chirp"]
    duration_s: float = Field(gt=0.0, le=3600.0, allow_inf_nan=False)
    f0_hz: float = Field(gt=0.0, allow_inf_nan=False)
    f1_hz: float = Field(gt=0.0, allow_inf_nan=False)
    method: Literal["linear", "logarithmic", "quadratic", "hyperbolic"] = "logarithmic"


class RunoutSpec(_Base):
    """No excitation at a running operating point: averages the synchronous response over the
    shaft angle (run-out filter, paper Sec. 4.4)."""

    kind: Literal["runout"]
    revolutions: int = Field(100, ge=10, le=1_000_000)
    controller: bool = False

    @model_validator(mode="after")
    def _turning(self):
        if self.operating_point is not None and self.operating_point.omega_rpm <= 0:
            raise ValueError("runout needs a turning shaft: operating_point.omega_rpm > 0")
        return self

    def duration_s(self, omega_rpm: float) -> float:
        """Record length for ``revolutions`` turns at ``omega_rpm``, s."""
        return self.revolutions * 60.0 / omega_rpm


class ImpactSpec(_Base):
    """Hammer impacts, horizontal (x) or vertical (y), with K∞ off and/or on."""

    kind: Literal["impact"]
    axis: Axis
    controller: list[bool] = Field(default_factory=lambda: [False, True], min_length=1,
                                   max_length=2)
    repeats: int = Field(3, ge=1, le=100)
    pre_s: float = Field(0.05, ge=0.0, le=10.0, allow_inf_nan=False)
    post_s: float = Field(0.5, gt=0.0, le=60.0, allow_inf_nan=False)
    spacing_s: float = Field(0.2, ge=0.0, le=60.0, allow_inf_nan=False)
    trigger: Literal["sim", "operator"] = "sim"
    peak_n: float = Field(20.0, gt=0.0, le=10000.0)       #: simulated hammer peak force, N
    pulse_s: float = Field(0.001, gt=0.0, le=0.1)          #: simulated hammer pulse length, s
    trigger_n: float = Field(5.0, gt=0.0)                   #: operator mode: force threshold, N
    timeout_s: float = Field(60.0, gt=0.0, le=3600.0)      #: operator mode: wait per hit, s

    @field_validator("controller")
    @classmethod
    def _unique(cls, v):
        if len(set(v)) != len(v):
            raise ValueError("controller states repeated")
        return v


class SettleSpec(StrictModel):
    """Settling check after a change of operating point (rig; on the sim it passes at once)."""

    tolerance_rpm: float = Field(20.0, gt=0.0)
    tolerance_bar: float = Field(0.05, gt=0.0)
    hold_s: float = Field(0.2, gt=0.0, le=600.0)
    timeout_s: float = Field(60.0, gt=0.0, le=7200.0)


class Grid(StrictModel):
    omega_rpm: list[float] = Field(min_length=1, max_length=200)
    p_inj_bar: list[float] = Field(min_length=1, max_length=200)

    @field_validator("omega_rpm")
    @classmethod
    def _omega(cls, v):
        if any(not (0.0 <= x <= 100000.0) for x in v):
            raise ValueError("speeds must be within [0, 100000] rpm")
        if len(set(v)) != len(v):
            raise ValueError("speed repeated in the grid")
        return v

    @field_validator("p_inj_bar")
    @classmethod
    def _p(cls, v):
        if any(not (0.0 <= x <= 50.0) for x in v):
            raise ValueError("pressures must be within [0, 50] bar")
        if len(set(v)) != len(v):
            raise ValueError("pressure repeated in the grid")
        return v


class SweepSpec(_Base):
    """A grid Ω × P_I with one experiment (``at_each``) at every point."""

    kind: Literal["sweep"]
    grid: Grid
    at_each: dict[str, Any]
    settle: SettleSpec = Field(default_factory=SettleSpec)
    set_point_by: Literal["loop", "operator"] = "loop"

    def points(self) -> list[OperatingPoint]:
        """Grid points, speed-major (all pressures at the first speed, then the next)."""
        return [OperatingPoint(omega_rpm=w, p_inj_bar=p)
                for w in self.grid.omega_rpm for p in self.grid.p_inj_bar]


PointSpec = PrbsSpec | MultilevelSpec | MultisineSpec | ChirpSpec | RunoutSpec | ImpactSpec
ExperimentSpec = PointSpec | SweepSpec
KINDS: dict[str, type] = {"prbs": PrbsSpec, "multilevel": MultilevelSpec,
                          "multisine": MultisineSpec, "chirp": ChirpSpec, "runout": RunoutSpec,
                          "impact": ImpactSpec, "sweep": SweepSpec}
EXCITATION_KINDS = ("prbs", "multilevel", "multisine", "chirp")


def _pick(loaded: LoadedYaml, section: tuple[str, ...], allowed: dict[str, type]) -> type:
    data = loaded.data
    for key in section:
        data = data[key]
    prefix = ".".join(section)
    where_top = f"{loaded.source}:{loaded.line_of(section) or 1}"
    if not isinstance(data, dict):
        raise InputError(f"expected a mapping with a 'kind' key, got {type(data).__name__}",
                         f"{where_top}: {prefix or '(top level)'}")
    if "kind" not in data:
        raise InputError(f"missing key 'kind' (one of {', '.join(allowed)})",
                         f"{where_top}: {prefix or '(top level)'}")
    kind = data["kind"]
    if kind not in allowed:
        line = loaded.line_of(section + ("kind",))
        raise InputError(f"unknown kind {kind!r} (one of {', '.join(allowed)})",
                         f"{loaded.source}:{line}: {(prefix + '.') if prefix else ''}kind")
    return allowed[kind]


def validate_spec(loaded: LoadedYaml) -> tuple[Any, PointSpec | None]:
    """Validate parsed YAML: ``(spec, point_spec)``; ``point_spec`` is the ``at_each`` of a
    sweep (validated with its own schema) or None."""
    model = _pick(loaded, (), KINDS)
    spec = validate(loaded, model)
    if isinstance(spec, SweepSpec):
        point_kinds = {k: v for k, v in KINDS.items() if k != "sweep"}
        pmodel = _pick(loaded, ("at_each",), point_kinds)
        if "operating_point" in loaded.data["at_each"]:
            line = loaded.line_of(("at_each", "operating_point"))
            raise InputError("not allowed inside a sweep (the grid sets the operating point)",
                             f"{loaded.source}:{line}: at_each.operating_point")
        point = validate(loaded, pmodel, section=("at_each",))
        if isinstance(point, RunoutSpec) and min(spec.grid.omega_rpm) <= 0:
            line = loaded.line_of(("grid", "omega_rpm"))
            raise InputError("runout at every point needs omega_rpm > 0 everywhere",
                             f"{loaded.source}:{line}: grid.omega_rpm")
        return spec, point
    return spec, None


def load_experiment(path: str | Path) -> tuple[Any, PointSpec | None, str]:
    """Read and validate an experiment YAML file: ``(spec, sweep_point_spec, yaml_text)``."""
    text = read_text(path, MAX_EXPERIMENT_BYTES, "experiment file")
    loaded = read_yaml(path, text)
    spec, point = validate_spec(loaded)
    return spec, point, text


def spec_from_dict(data: dict[str, Any], source: str = "<spec>") -> tuple[Any, PointSpec | None]:
    """Validate an inline spec (e.g. from the control socket)."""
    return validate_spec(LoadedYaml(data, {}, source))
