"""The in-memory measurement record shared by every modelling command."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.errors import InputError

#: Columns of a rotor record (interchange CSV names).
ACTUATOR_INPUTS = ("r_x", "r_y")
ACTUATOR_OUTPUTS = ("u_x", "u_y")
BEARING_INPUTS = ("u_x", "u_y")
BEARING_OUTPUTS = ("e_x", "e_y")


@dataclass
class Record:
    """A uniformly sampled multichannel record.

    Attributes
    ----------
    columns : dict[str, numpy.ndarray]
        Channel name -> float64 array, all of the same length. Names and units follow the
        interchange CSV (``e_x`` in µm, ``u_x`` in V, ``phi`` in rad, ...).
    fs : float
        Sample rate, Hz.
    meta : dict
        Metadata: ``omega_rpm``, ``p_inj_bar``, ``kind``, ``inputs``/``outputs`` (generic
        records), and anything else the file carried.
    source : str
        Where the record came from (a path), used in error messages.
    """

    columns: dict[str, np.ndarray]
    fs: float
    meta: dict[str, Any] = field(default_factory=dict)
    source: str = "<memory>"

    def __post_init__(self) -> None:
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise InputError(f"columns of unequal length {sorted(lengths)}", self.source)
        if not (np.isfinite(self.fs) and self.fs > 0):
            raise InputError(f"sample rate fs must be a positive number, got {self.fs!r}",
                             self.source)

    # --- basic properties -------------------------------------------------------------
    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self)

    @property
    def dt(self) -> float:
        """Sample period, s."""
        return 1.0 / self.fs

    @property
    def omega_rpm(self) -> float:
        """Shaft speed Ω during the record, rpm (0 if not stated)."""
        return float(self.meta.get("omega_rpm", 0.0) or 0.0)

    @property
    def p_inj_bar(self) -> float | None:
        """Injection pressure P_I (manometric), bar, or None for non-rotor records."""
        v = self.meta.get("p_inj_bar")
        return None if v is None else float(v)

    @property
    def kind(self) -> str | None:
        """Experiment kind (``prbs``, ``runout``, ``impact``, ``free``...) if known."""
        return self.meta.get("kind")

    @property
    def is_generic(self) -> bool:
        """True for records that declare their own ``inputs``/``outputs`` channels."""
        return bool(self.meta.get("inputs")) and bool(self.meta.get("outputs"))

    @property
    def inputs(self) -> list[str]:
        """Declared input channels of a generic record (empty for rotor records)."""
        return list(self.meta.get("inputs") or [])

    @property
    def outputs(self) -> list[str]:
        """Declared output channels of a generic record (empty for rotor records)."""
        return list(self.meta.get("outputs") or [])

    def has(self, *names: str) -> bool:
        """True if every named column is present."""
        return all(n in self.columns for n in names)

    def col(self, name: str) -> np.ndarray:
        """The named column; :class:`InputError` naming the file if it is missing."""
        try:
            return self.columns[name]
        except KeyError:
            raise InputError(f"record has no column {name!r} (has: {', '.join(self.columns)})",
                             self.source) from None

    def matrix(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """Columns stacked as an (n_samples, len(names)) float64 array."""
        return np.column_stack([self.col(n) for n in names]).astype(float, copy=False)

    # --- derived records --------------------------------------------------------------
    def slice(self, start: int | None = None, stop: int | None = None) -> Record:
        """Samples ``start:stop`` as a new record (metadata copied)."""
        cols = {k: v[start:stop] for k, v in self.columns.items()}
        return Record(cols, self.fs, dict(self.meta), self.source)

    def with_columns(self, **cols: np.ndarray) -> Record:
        """A copy with some columns added or replaced."""
        new = dict(self.columns)
        new.update({k: np.asarray(v, dtype=float) for k, v in cols.items()})
        return Record(new, self.fs, dict(self.meta), self.source)
