"""The in-memory measurement record shared by every modelling command."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.errors import InputError

#: Unparsable cells remembered per column (their text, for the message naming the first).
BAD_CELLS_KEPT = 100
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
    lines : numpy.ndarray or None
        The file line of each sample (CSV readers), for messages naming a bad cell.
    first_sample : int
        Index in the source of this record's sample 0 (``slice`` keeps it), for messages.
    bad_cells : dict[str, dict[int, str]]
        Cells that did not parse as numbers (read as NaN), column -> {file line: text}; at
        most :data:`BAD_CELLS_KEPT` per column. Only the columns a command uses are checked
        (:meth:`check_finite`), so an unused column with empty cells does not refuse a record.
    """

    columns: dict[str, np.ndarray]
    fs: float
    meta: dict[str, Any] = field(default_factory=dict)
    source: str = "<memory>"
    lines: np.ndarray | None = None
    first_sample: int = 0
    bad_cells: dict[str, dict[int, str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise InputError(f"columns of unequal length {sorted(lengths)}", self.source)
        if not (np.isfinite(self.fs) and self.fs > 0):
            raise InputError(f"sample rate fs must be a positive number, got {self.fs!r}",
                             self.source)
        if self.lines is not None and len(self.lines) != len(self):
            self.lines = None  # columns replaced by a caller: no longer line by line

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

    def check_finite(self, names: tuple[str, ...] | list[str], use: str = "") -> None:
        """Refuse the record if a column in use holds an empty, non-numeric, NaN or Inf cell.

        Parameters
        ----------
        names : list of str
            The columns the caller uses (others are not looked at).
        use : str
            What uses them, for the message (e.g. ``"the bearing model"``).

        Raises
        ------
        InputError
            One line naming the file (and line, for CSV), the column and the sample.
        """
        if self.lines is None and "rigd_version" in self.meta:
            self._check_valid(names, use)     # rigd's recording: stretches of invalid samples
        for name in names:
            col = self.col(name)
            bad = ~np.isfinite(col)
            if not bad.any():
                continue
            i = int(np.argmax(bad))
            nbad = int(bad.sum())
            line = int(self.lines[i]) if self.lines is not None else None
            text = self.bad_cells.get(name, {}).get(line) if line is not None else None
            if text is not None:
                what = "empty cell" if not text.strip() else f"non-numeric cell {text.strip()!r}"
            else:
                what = "NaN" if np.isnan(col[i]) else repr(float(col[i]))
            more = f" ({nbad - 1} more in this column)" if nbad > 1 else ""
            by = f", used by {use}" if use else ""
            where = (f"{self.source}:{line}" if line is not None else self.source)
            raise InputError(f"{what} in column {name!r} at sample {self.first_sample + i}"
                             f"{by}{more}; only the columns in use must be complete", where)

    def _check_valid(self, names, use: str) -> None:
        """A recording (not a CSV file) with invalid samples — NaN where a driver was
        disconnected or its data stale (docs/data.md, "Invalid samples") — in the columns in
        use: refused in one line naming the first invalid stretch and the longest valid one,
        to choose with ``--range``."""
        bad = np.zeros(len(self), dtype=bool)
        first = None
        for name in names:
            b = ~np.isfinite(self.col(name))
            if b.any() and first is None:
                first = name
            bad |= b
        if first is None:
            return
        raise invalid_samples_error(bad, self.fs, self.first_sample, first, use, self.source)

    def matrix(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """Columns stacked as an (n_samples, len(names)) float64 array."""
        return np.column_stack([self.col(n) for n in names]).astype(float, copy=False)

    # --- derived records --------------------------------------------------------------
    def slice(self, start: int | None = None, stop: int | None = None) -> Record:
        """Samples ``start:stop`` as a new record (metadata copied)."""
        cols = {k: v[start:stop] for k, v in self.columns.items()}
        a = range(len(self))[start:stop].start if len(self) else 0
        return Record(cols, self.fs, dict(self.meta), self.source,
                      None if self.lines is None else self.lines[start:stop],
                      self.first_sample + a, self.bad_cells)

    def with_columns(self, **cols: np.ndarray) -> Record:
        """A copy with some columns added or replaced."""
        new = dict(self.columns)
        new.update({k: np.asarray(v, dtype=float) for k, v in cols.items()})
        return Record(new, self.fs, dict(self.meta), self.source, self.lines,
                      self.first_sample, self.bad_cells)


def valid_stretches(valid: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` sample indices of the runs of True in ``valid`` (a record's valid
    samples), in order."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(valid, np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def invalid_samples_error(bad: np.ndarray, fs: float, offset: int, column: str, use: str,
                          source: str) -> InputError:
    """The one-line refusal of a recording whose samples ``bad`` (True: invalid, NaN) are in
    use: the count, the first invalid stretch and the longest valid one as a ``--range``
    (sample indices from ``offset``, times at ``fs``)."""
    runs = valid_stretches(~bad)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], bad.astype(np.int8), [0]])))
    a, b = int(edges[0]), int(edges[1])
    by = f", used by {use}" if use else ""
    pick = ""
    if runs:
        c, d = max(runs, key=lambda r: r[1] - r[0])
        pick = f"; the longest valid stretch is --range {offset + c}:{offset + d} " \
               f"({(d - c) / fs:.3g} s)"
    first = (f"sample {offset + a} (t {(offset + a) / fs:.4g} s)" if b - a == 1 else
             f"samples {offset + a}:{offset + b} (t {(offset + a) / fs:.4g}-"
             f"{(offset + b) / fs:.4g} s)")
    return InputError(
        f"{int(bad.sum())} invalid samples (NaN: no valid data from the driver, the record's "
        f"fault column says why) in column {column!r}{by}, in {len(edges) // 2} stretch(es), "
        f"the first at {first}; choose a valid stretch with --range{pick}", source)
