"""Read a MATLAB ``.mat`` file (v5 through scipy.io.loadmat, v7.3 through h5py) as a record.

A MAT-file carries matrices, not a sample rate or roles: the user says which matrix
(``var``), which of its columns are inputs and outputs and which is the time, or the rate::

    rigd identify dryer2.mat --var dryer2 --time-column 1 --inputs 2:4 --outputs 5:7

Columns are 1-based (MATLAB's numbering), as ``N``, ``A:B`` (inclusive) or lists of both
(``2:4,6``); the record names them ``col<N>``. Where the file has names — variables of their
own, such as the ``u`` and ``y`` of an ``iddata`` export — a token may be a variable's name
instead: its columns become ``<name>`` (one column) or ``<name>_<k>``. One sample a row (a
matrix with more columns than rows is refused, as MATLAB's ``iddata`` would need it
transposed). v7.3 files are HDF5 with MATLAB's layout (each dataset stored transposed),
undone here. Every refusal is one :class:`~rigd.errors.InputError` naming the file, the
variable and the column.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from rigd.data import compressed, csvio
from rigd.data.record import Record
from rigd.errors import InputError

#: the text every MAT-file (v4 excluded) starts with
MAT_MAGIC = b"MATLAB"
_RANGE = re.compile(r"^(\d+)(?::(\d+))?$")


def is_mat(path: str | Path) -> bool:
    """True if the file (or its gzip content) starts with a MAT-file (v5/v7/v7.3) text
    header."""
    return compressed.head(path, 6) == MAT_MAGIC


def _variables(path: Path) -> dict[str, np.ndarray]:
    """Numeric 2-D matrices of the file by name (v5 or v7.3); other variables left out."""
    spath = str(path)
    src: Any = compressed.read_bytes(path) if compressed.is_gzip(path) else path
    head = compressed.head(path, 128)
    out: dict[str, Any] = {}
    if head[124:128] == b"\x00\x02IM" or b"MATLAB 7.3" in head[:20]:
        import h5py

        try:
            with h5py.File(src, "r") as f:
                for name, ds in f.items():
                    if isinstance(ds, h5py.Dataset) and not name.startswith("#"):
                        cls = ds.attrs.get("MATLAB_class", b"double")
                        cls = cls.decode() if isinstance(cls, bytes) else str(cls)
                        if cls in ("double", "single") or cls.startswith(("int", "uint")):
                            out[name] = np.asarray(ds[()], dtype=float).T  # column-major
                        else:
                            out[name] = None
                    else:
                        out[name] = None
        except OSError as exc:
            raise InputError(f"cannot read as a MATLAB v7.3 (HDF5) file: {exc}", spath) from None
        return out
    import scipy.io

    try:
        raw = scipy.io.loadmat(src, squeeze_me=False)
    except (ValueError, TypeError, OSError, NotImplementedError) as exc:
        raise InputError(f"cannot read as a MATLAB file: {exc}", spath) from None
    for name, v in raw.items():
        if name.startswith("__"):
            continue
        ok = isinstance(v, np.ndarray) and v.dtype.kind in "fiub" and v.ndim == 2
        out[name] = v.astype(float) if ok else None
    return out


def _pick(variables: dict[str, Any], var: str | None, spath: str) -> tuple[str, np.ndarray]:
    numeric = {k: v for k, v in variables.items() if v is not None}
    if var is None:
        if len(numeric) != 1:
            names = ", ".join(sorted(numeric)) or "none"
            raise InputError(f"{len(numeric)} numeric matrices in the file ({names}): name "
                             "one with --var", spath)
        var = next(iter(numeric))
    if var not in variables:
        raise InputError(f"no variable {var!r} (the file has: "
                         f"{', '.join(sorted(variables)) or 'nothing'})", spath)
    m = variables[var]
    if m is None:
        raise InputError(f"variable {var!r} is not a numeric matrix (struct, cell, text or "
                         "object): save the data as a plain matrix", spath)
    if m.shape[0] < m.shape[1]:
        raise InputError(f"variable {var!r} is {m.shape[0]}x{m.shape[1]}: one sample a row "
                         "expected (more columns than rows; transpose it in MATLAB)", spath)
    return var, m


def _tokens(spec: str | list[str] | None) -> list[str]:
    if spec is None:
        return []
    items = spec.split(",") if isinstance(spec, str) else list(spec)
    return [s.strip() for s in items if s.strip()]


def _columns(spec, what: str, var: str, m: np.ndarray, variables: dict[str, Any],
             spath: str, n: int) -> dict[str, np.ndarray]:
    """Named columns of one option (``--inputs``, ``--outputs``, ``--time-column``)."""
    out: dict[str, np.ndarray] = {}
    ncol = m.shape[1]
    for tok in _tokens(spec):
        hit = _RANGE.match(tok)
        if hit:
            a = int(hit.group(1))
            b = int(hit.group(2) or a)
            if a < 1 or b < a:
                raise InputError(f"{what}: bad column range {tok!r} (1-based, A:B with "
                                 "1 <= A <= B)", f"{spath}: variable {var!r}")
            if b > ncol:
                raise InputError(f"{what}: column {b} does not exist (variable {var!r} has "
                                 f"{ncol} columns)", f"{spath}: variable {var!r}")
            for c in range(a, b + 1):
                out[f"col{c}"] = np.ascontiguousarray(m[:, c - 1])
            continue
        v = variables.get(tok)
        if v is None:
            known = ", ".join(sorted(k for k, x in variables.items() if x is not None))
            raise InputError(f"{what}: {tok!r} is neither a 1-based column range of "
                             f"{var!r} nor a numeric variable of the file ({known})", spath)
        if v.shape[0] < v.shape[1]:
            v = v.T   # a row vector named by the user: its samples run along the row
        if v.shape[0] != n:
            raise InputError(f"{what}: variable {tok!r} has {v.shape[0]} samples, "
                             f"{var!r} has {n}", spath)
        for k in range(v.shape[1]):
            out[tok if v.shape[1] == 1 else f"{tok}_{k + 1}"] = np.ascontiguousarray(v[:, k])
    return out


def read_mat(path: str | Path, *, var: str | None = None, inputs=None, outputs=None,
             time_column: str | int | None = None, fs: float | None = None,
             meta: dict[str, Any] | None = None) -> Record:
    """Read a MAT-file into a generic :class:`Record` (module docstring).

    Parameters
    ----------
    path : path
        ``.mat`` file, v5/v7 (scipy) or v7.3 (HDF5), or the same gzip-compressed.
    var : str, optional
        The matrix holding the samples (needed when the file has several).
    inputs, outputs : str or list of str
        1-based columns of ``var`` (``"2:4"``, ``"2,5"``) or names of variables of the file.
    time_column : str or int, optional
        1-based column (or variable) holding the time in seconds; gives ``fs`` and becomes
        the record's ``t`` (checked as a CSV's: increasing, uniform within half a sample).
    fs : float, optional
        Sample rate (Hz) when there is no time column; with one, the two must agree.
    meta : dict, optional
        Further metadata.

    Raises
    ------
    InputError
        Unreadable file, unknown variable or column, no rate, a bad time column.
    """
    p = Path(path)
    spath = str(path)
    variables = _variables(p)
    var, m = _pick(variables, var, spath)
    where = f"{spath}: variable {var!r}"
    n = m.shape[0]
    ins = _columns(inputs, "--inputs", var, m, variables, spath, n)
    outs = _columns(outputs, "--outputs", var, m, variables, spath, n)
    if not ins or not outs:
        raise InputError("give the input and output columns (--inputs and --outputs, "
                         "1-based, e.g. --inputs 2:3 --outputs 4)", where)
    both = set(ins) & set(outs)
    if both:
        raise InputError(f"column(s) {', '.join(sorted(both))} given as input and as output",
                         where)
    columns = {**ins, **outs}
    lines = np.arange(1, n + 1)
    if time_column is not None:
        tc = _columns(str(time_column), "--time-column", var, m, variables, spath, n)
        if len(tc) != 1:
            raise InputError(f"--time-column: one column expected, got {len(tc)}", where)
        (tname, t), = tc.items()
        if tname in columns:
            raise InputError(f"--time-column: {tname} is also an input or output", where)
        if n < 2:
            raise InputError("a time column needs at least 2 samples", where)
        if not np.all(np.isfinite(t)):
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise InputError(f"time column {tname}: not a finite number at row {i + 1}", where)
        dt = float(np.median(np.diff(t)))
        if not dt > 0:
            raise InputError(f"time column {tname} does not increase", where)
        fs_t = 1.0 / dt
        if fs is not None and abs(fs - fs_t) > 1e-6 * fs:
            raise InputError(f"--fs {fs:g} Hz disagrees with the time column {tname} "
                             f"({fs_t:g} Hz)", where)
        fs = fs if fs is not None else fs_t
        csvio.check_time(t, fs, lines, f"{spath}: variable {var!r} column {tname} row")
        columns = {"t": np.ascontiguousarray(t), **columns}
    elif fs is None:
        raise InputError("no sample rate: give --fs HZ or --time-column N", where)
    if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
        raise InputError(f"fs must be a positive number of Hz, got {fs!r}", where)
    meta = dict(meta or {})
    meta.update(inputs=list(ins), outputs=list(outs), source_file=p.name, mat_variable=var)
    return Record(columns, float(fs), meta, spath, None, 0, {})
