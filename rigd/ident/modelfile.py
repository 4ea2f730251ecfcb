"""Model files: identified sub-models as one YAML file, written atomically.

Layout (``rigd_model: 1``)::

    rigd_model: 1
    created: 2026-11-22T03:40:00Z
    fs_hz: 5000.0
    data: {path: prbs.csv, sha256: "..."}
    operating_point: {omega_rpm: 0.0, p_inj_bar: 4.0}
    prefilters: {runout: ..., offsets: {samples: 2000, values: {...}}, median: {...}}
    split: {estimation: [0, 20000], validation: [20000, 30000]}
    submodels:
      bearing:
        structure: {kind: bearing, inputs: [u_x, u_y], outputs: [e_x, e_y], effects: []}
        method: pem
        parameters: {d_xx: {value: 34.5, std: 0.01}, ...}
        fit_percent: {estimation: [98.1, 97.9], validation: [98.0, 97.8]}
        readouts: {modes: [{f_n_hz: 110.5, zeta: 0.05}, ...], static_gain: [[...]]}
      actuator: {...}

:func:`load_model` rebuilds each sub-model's structure and theta, re-applying the effects a
sub-model names through the resolver it is given (``rigd.effects.resolve``: identification
does not import the effect catalogue, the catalogue builds on identification);
:meth:`ModelFile.ss` gives python-control StateSpace objects and :meth:`ModelFile.plant` the
cascade G_p = G_bear·G_act.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from rigd.configio import StrictModel, dump_yaml, read_yaml, validate
from rigd.errors import InputError
from rigd.ident.greybox.submodels import structure_for
from rigd.ident.model import base_of
from rigd.plain import plain

FORMAT = 1


def sha256_file(path: str | Path) -> str:
    """``sha256:<hex>`` of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return "sha256:" + h.hexdigest()


# --- schema ---------------------------------------------------------------------------
class ParamEntry(StrictModel):
    value: float
    std: float | None = None


class StructureSpec(StrictModel):
    kind: str
    inputs: list[str]
    outputs: list[str]
    n: int | None = None
    nu: int | None = None
    hold: str | None = None
    effects: list[str] = Field(default_factory=list)
    #: parallel modes beyond one per output (generic, rigd.ident.greybox.parallel)
    extra_modes: int = Field(0, ge=0)
    #: generic: a constant offset per output is a parameter (``yoff_i``; absent in files
    #: written before it existed, which rebuild without it)
    output_offsets: bool = False
    #: general LTI / process families (rigd.ident.lti): the rate the poles are relative to,
    #: block counts, per-input delays (samples), free D, C's normalised rows, process kind
    fs_hz: float | None = None
    blocks: dict[str, int] | None = None
    delays: list[int] | None = None
    feedthrough: bool = False
    norm_rows: list[int] | None = None
    process: str | None = None


class SubmodelEntry(StrictModel):
    structure: StructureSpec
    method: str = "pem"
    parameters: dict[str, ParamEntry]
    fit_percent: dict[str, Any] = Field(default_factory=dict)
    readouts: dict[str, Any] = Field(default_factory=dict)
    residual: dict[str, Any] = Field(default_factory=dict)


class ModelFileSchema(StrictModel):
    rigd_model: int
    created: str | None = None
    fs_hz: float = Field(gt=0)
    data: dict[str, Any] = Field(default_factory=dict)
    operating_point: dict[str, Any] = Field(default_factory=dict)
    prefilters: dict[str, Any] = Field(default_factory=dict)
    split: dict[str, Any] = Field(default_factory=dict)
    submodels: dict[str, SubmodelEntry]


# --- in memory ------------------------------------------------------------------------
@dataclass
class Submodel:
    """One identified sub-model: structure, parameters and what was measured about it."""

    name: str
    structure: Any
    theta: np.ndarray
    std: np.ndarray
    method: str = "pem"
    fit_percent: dict[str, Any] = field(default_factory=dict)
    readouts: dict[str, Any] = field(default_factory=dict)
    residual: dict[str, Any] = field(default_factory=dict)

    @property
    def parameters(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.structure.names, self.theta)}

    def ss(self):
        """Continuous python-control StateSpace of the (linear part of the) sub-model."""
        st = base_of(self.structure)  # parallel modes are the base's own
        return st.ss(np.asarray(self.theta)[:len(st.names)])

    def linear_ss(self, fs: float, G0=None):
        """(G, included, left_out): the sub-model as a linear design model — its base's
        linear part (or ``G0`` in its place: a range model of the same base) with the
        small-signal linear block of each effect that has one (a delay as a Padé
        approximant, an extra mode, lags; ``Effect.linear``), ``included`` their names and
        ``left_out`` {name: why} of the others (hysteresis, run-out, …). ``fs``: the rate
        of the fit, Hz (effect parameters in samples)."""
        return self.structure.linear_ss(np.asarray(self.theta, float), fs, G0)


@dataclass
class ModelFile:
    """A model file in memory (see module docstring)."""

    fs: float
    submodels: dict[str, Submodel]
    operating_point: dict[str, Any] = field(default_factory=dict)
    prefilters: dict[str, Any] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)
    split: dict[str, Any] = field(default_factory=dict)
    created: str | None = None
    source: str = "<memory>"

    def ss(self, name: str, effects: bool = False):
        """Continuous StateSpace of sub-model ``name``: its base's linear part, or with
        ``effects`` the linear blocks of its effects too (:meth:`Submodel.linear_ss`);
        InputError if the file has no such sub-model."""
        if name not in self.submodels:
            raise InputError(f"model has no {name!r} sub-model (has: "
                             f"{', '.join(self.submodels)})", self.source)
        sm = self.submodels[name]
        return sm.linear_ss(self.fs)[0] if effects else sm.ss()

    def plant(self, effects: bool = False):
        """G_p(s) = G_bear(s)·G_act(s): r = [r_x, r_y] -> p = [e_x, e_y] (needs both): the
        base parts, or with ``effects`` the linear blocks of the sub-models' effects too."""
        return self.ss("bearing", effects) * self.ss("actuator", effects)

    def linear_effects(self) -> dict[str, dict[str, Any]]:
        """Sub-model -> {``included``: effects whose linear block :meth:`plant` carries,
        ``left_out``: {effect: why not}}."""
        out = {}
        for name, sm in self.submodels.items():
            _, inc, left = sm.linear_ss(self.fs)
            out[name] = {"included": inc, "left_out": left}
        return out

    def to_dict(self) -> dict[str, Any]:
        subs = {}
        for name, sm in self.submodels.items():
            spec = dict(base_of(sm.structure).spec())  # parallel modes are the base's own
            spec["effects"] = list(sm.structure.effects)
            subs[name] = {
                "structure": spec,
                "method": sm.method,
                "parameters": {n: {"value": float(v), "std": float(s)}
                               for n, v, s in zip(sm.structure.names, sm.theta, sm.std)},
                "fit_percent": plain(sm.fit_percent),
                "readouts": plain(sm.readouts),
                "residual": plain(sm.residual),
            }
        return {"rigd_model": FORMAT,
                "created": self.created or _dt.datetime.now(_dt.timezone.utc).strftime(
                    "%Y-%m-%dT%H:%M:%SZ"),
                "fs_hz": float(self.fs), "data": plain(self.data),
                "operating_point": plain(self.operating_point),
                "prefilters": plain(self.prefilters), "split": plain(self.split),
                "submodels": subs}

    def save(self, path: str | Path) -> Path:
        """Write atomically (temporary file + rename)."""
        dump_yaml(path, self.to_dict())
        return Path(path)


EffectResolver = Callable[[Sequence[str], "str | None"], Sequence[Any]]


def rebuild_structure(spec: StructureSpec | dict, where: str = "<model>",
                      resolve_effects: EffectResolver | None = None):
    """The structure a spec describes, with its effects re-applied.

    ``resolve_effects(names, where)`` turns the spec's effect names into effects (objects with
    ``extend(structure)``), e.g. ``rigd.effects.resolve``; it is needed only when the spec
    names effects.
    """
    if isinstance(spec, dict):
        spec = StructureSpec.model_validate(spec)
    if spec.kind not in ("actuator", "bearing", "generic", "lti", "process"):
        raise InputError(f"unknown structure kind {spec.kind!r}", where)
    if spec.kind in ("lti", "process"):
        from rigd.ident.lti.process import ProcessModel
        from rigd.ident.lti.statespace import StateSpaceModel

        if spec.fs_hz is None:
            raise InputError(f"a {spec.kind} structure needs fs_hz", where)
        try:
            st = (StateSpaceModel if spec.kind == "lti" else ProcessModel).from_spec(
                spec.model_dump())
        except ValueError as exc:
            raise InputError(str(exc), where) from None
    else:
        st = structure_for(spec.kind, spec=spec.model_dump())
    if spec.extra_modes:
        if spec.kind != "generic":
            raise InputError("extra_modes is for generic structures only", where)
        st = st.with_modes(spec.extra_modes)
    if spec.effects:
        if resolve_effects is None:
            raise InputError(f"the structure names effects ({', '.join(spec.effects)}) but no "
                             "effect catalogue was given to rebuild them "
                             "(load_model(path, resolve_effects=rigd.effects.resolve))", where)
        try:
            st = apply_effects(st, resolve_effects(spec.effects, where))
        except ValueError as exc:  # an effect the base cannot carry (Effect.not_offered)
            raise InputError(str(exc), where) from None
    return st


def apply_effects(structure, effects: Sequence[Any]):
    """``structure`` extended by ``effects`` (objects with ``extend(structure)``), in order."""
    for e in effects:
        structure = e.extend(structure)
    return structure


def load_model(path: str | Path, resolve_effects: EffectResolver | None = None) -> ModelFile:
    """Read a model file; any problem -> InputError naming the file, line and key.

    Parameters
    ----------
    path : str or Path
        The model file (YAML, ``rigd_model: 1``).
    resolve_effects : callable, optional
        ``(names, where) -> effects``, normally ``rigd.effects.resolve``: rebuilds the effects
        a sub-model names (a file naming effects is refused without it).
    """
    loaded = read_yaml(path)
    doc = validate(loaded, ModelFileSchema)
    if doc.rigd_model != FORMAT:
        raise InputError(f"unsupported model file version {doc.rigd_model} (this rigd reads "
                         f"{FORMAT})", str(path))
    subs = {}
    for name, e in doc.submodels.items():
        where = f"{path}:{loaded.line_of(('submodels', name)) or ''}: submodels.{name}"
        st = rebuild_structure(e.structure, where, resolve_effects)
        missing = [n for n in st.names if n not in e.parameters]
        if missing:
            raise InputError(f"parameter(s) {', '.join(missing)} missing", where)
        theta = np.array([e.parameters[n].value for n in st.names])
        std = np.array([e.parameters[n].std or 0.0 for n in st.names])
        if not np.all(np.isfinite(theta)):
            raise InputError("non-finite parameter value", where)
        subs[name] = Submodel(name, st, theta, std, e.method, e.fit_percent, e.readouts,
                              e.residual)
    return ModelFile(doc.fs_hz, subs, doc.operating_point, doc.prefilters, doc.data,
                     doc.split, doc.created, str(path))
