"""Identification data: inputs, outputs, sample rate and auxiliary channels of one record.

:class:`IdData` is what every structure simulates and every fit consumes. It is built from a
:class:`rigd.data.Record` for one sub-model:

* ``"actuator"`` (Eqs. 8-10): inputs ``r_x, r_y`` (V) -> outputs ``u_x, u_y`` (V);
* ``"bearing"`` (Eqs. 5-7): inputs ``u_x, u_y`` (V) -> outputs ``e_x, e_y`` (µm);
* ``"generic"``: the record's declared ``inputs`` -> ``outputs`` (any units).
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rigd.data.record import (
    ACTUATOR_INPUTS,
    ACTUATOR_OUTPUTS,
    BEARING_INPUTS,
    BEARING_OUTPUTS,
    Record,
)
from rigd.errors import InputError

#: Fewest samples a record must have to be identified (offsets use the first 2000).
MIN_SAMPLES = 500

SUBMODELS = ("actuator", "bearing", "generic")


@dataclass
class IdData:
    """Uniformly sampled input/output data of one sub-model.

    Attributes
    ----------
    u : ndarray, shape (n, nu)
        Inputs (V for rotor sub-models).
    y : ndarray, shape (n, ny)
        Outputs (V for the actuator, µm for the bearing).
    fs : float
        Sample rate, Hz.
    input_names, output_names : list of str
        Channel names.
    aux : dict of str -> ndarray (n,)
        Auxiliary channels, e.g. ``phi`` (shaft angle, rad), ``omega`` (rad/s) and, for the
        actuator, the valve drives ``v_1``..``v_4`` (V).
    meta : dict
        Operating point (``omega_rpm``, ``p_inj_bar``), source, sub-model name.
    """

    u: np.ndarray
    y: np.ndarray
    fs: float
    input_names: list[str]
    output_names: list[str]
    aux: dict[str, np.ndarray] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.u = np.ascontiguousarray(np.atleast_2d(np.asarray(self.u, float).T).T)
        self.y = np.ascontiguousarray(np.atleast_2d(np.asarray(self.y, float).T).T)
        if self.u.shape[0] != self.y.shape[0]:
            raise InputError(f"inputs have {self.u.shape[0]} samples, outputs {self.y.shape[0]}",
                             self.source)

    # aliases used by rigd.effects (docs/ARCHITECTURE.md names)
    @property
    def inputs(self) -> np.ndarray:
        """Inputs (n, nu); alias of ``u``."""
        return self.u

    @property
    def outputs(self) -> np.ndarray:
        """Outputs (n, ny); alias of ``y``."""
        return self.y

    @property
    def phi(self) -> np.ndarray | None:
        """Shaft angle (rad) if the record had one."""
        return self.aux.get("phi")

    def with_inputs(self, u: np.ndarray) -> IdData:
        """A copy with inputs replaced (same outputs, aux, meta)."""
        return self.with_u(u)

    def with_outputs(self, y: np.ndarray) -> IdData:
        """A copy with outputs replaced."""
        return self.with_y(y)

    @property
    def n(self) -> int:
        """Number of samples."""
        return self.y.shape[0]

    @property
    def nu(self) -> int:
        return self.u.shape[1]

    @property
    def ny(self) -> int:
        return self.y.shape[1]

    @property
    def dt(self) -> float:
        return 1.0 / self.fs

    @property
    def source(self) -> str:
        return str(self.meta.get("source", "<memory>"))

    @property
    def submodel(self) -> str:
        return str(self.meta.get("submodel", "generic"))

    def slice(self, start: int | None = None, stop: int | None = None) -> IdData:
        """Samples ``start:stop`` as new data (aux channels sliced alike)."""
        return replace(self, u=self.u[start:stop], y=self.y[start:stop],
                       aux={k: v[start:stop] for k, v in self.aux.items()},
                       meta=dict(self.meta))

    def with_y(self, y: np.ndarray) -> IdData:
        return replace(self, y=np.asarray(y, float), aux=dict(self.aux), meta=dict(self.meta))

    def with_u(self, u: np.ndarray) -> IdData:
        return replace(self, u=np.asarray(u, float), aux=dict(self.aux), meta=dict(self.meta))

    def split(self, frac: float = 2.0 / 3.0) -> tuple[IdData, IdData]:
        """Estimation part (first ``frac``) and validation part (the rest)."""
        k = int(round(self.n * frac))
        return self.slice(0, k), self.slice(k, None)


def channels_for(record: Record, submodel: str) -> tuple[list[str], list[str]]:
    """Input and output column names of ``submodel`` for ``record``."""
    if submodel == "actuator":
        return list(ACTUATOR_INPUTS), list(ACTUATOR_OUTPUTS)
    if submodel == "bearing":
        return list(BEARING_INPUTS), list(BEARING_OUTPUTS)
    if submodel == "generic":
        if not record.is_generic:
            raise InputError("record declares no 'inputs'/'outputs' metadata for a generic "
                             "model", record.source)
        return record.inputs, record.outputs
    raise InputError(f"unknown sub-model {submodel!r} (known: {', '.join(SUBMODELS)})",
                     record.source)


#: per-valve PD drive voltages (V) carried as aux channels of actuator data
DRIVE_CHANNELS = ("v_1", "v_2", "v_3", "v_4")


def from_record(record: Record, submodel: str, min_samples: int = MIN_SAMPLES) -> IdData:
    """Build :class:`IdData` for one sub-model; missing columns or a short record -> InputError."""
    ins, outs = channels_for(record, submodel)
    missing = [c for c in ins + outs if c not in record.columns]
    if missing:
        raise InputError(f"the {submodel} model needs column(s) {', '.join(missing)} "
                         f"(record has: {', '.join(record.columns)})", record.source)
    if record.n < min_samples:
        what = ("identification" if min_samples == MIN_SAMPLES
                else f"the {submodel} model (its initial states are estimated on the record)")
        raise InputError(f"record too short for {what}: {record.n} samples, need at "
                         f"least {min_samples}", record.source)
    record.check_finite(ins + outs, f"the {submodel} model")
    aux = {}  # optional channels: carried only when complete
    if "phi" in record.columns and np.all(np.isfinite(record.columns["phi"])):
        aux["phi"] = np.asarray(record.columns["phi"], float)
    if submodel == "actuator":  # the valve drives v_1..v_4 (where hysteresis/creep act)
        for c in DRIVE_CHANNELS:
            if c in record.columns and np.all(np.isfinite(record.columns[c])):
                aux[c] = np.asarray(record.columns[c], float)
    meta = {"source": record.source, "submodel": submodel,
            "omega_rpm": record.omega_rpm, "p_inj_bar": record.p_inj_bar}
    return IdData(record.matrix(ins), record.matrix(outs), record.fs, ins, outs, aux, meta)


# --------------------------------------------------------------------------------------
# helpers for any data object with inputs/outputs/fs (IdData or a look-alike)
# --------------------------------------------------------------------------------------
def replace_inputs(data: Any, u: np.ndarray) -> Any:
    """A shallow copy of ``data`` whose ``inputs`` are ``u`` (n, nu)."""
    u = np.asarray(u, dtype=float)
    if hasattr(data, "with_inputs"):
        return data.with_inputs(u)
    if dataclasses.is_dataclass(data):
        return dataclasses.replace(data, inputs=u)
    new = copy.copy(data)
    new.inputs = u
    return new


def get_phi(data: Any) -> np.ndarray | None:
    """The shaft angle (rad) carried by ``data``, or None."""
    phi = getattr(data, "phi", None)
    if phi is None:
        aux = getattr(data, "aux", None) or {}
        phi = aux.get("phi") if isinstance(aux, dict) else None
    return None if phi is None else np.asarray(phi, dtype=float)
