"""Loading records for the modelling functions: files, plain CSV, sample ranges, provenance.

Every modelling function of :mod:`rigd.api` takes either a loaded
:class:`~rigd.data.record.Record` or a path, which goes through :func:`load`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from rigd.data.record import Record
from rigd.errors import InputError

#: What a record or run directory says about where it came from (``source`` metadata).
SOURCES = ("simulated", "rig")


def parse_fs(text: str | float) -> float:
    """A sample rate from ``"610.35"`` or a ratio ``"10000000/16384"``.

    Parameters
    ----------
    text : str or float
        Hz, a number or ``a/b``.

    Returns
    -------
    float
        The sample rate, Hz (positive, finite).

    Raises
    ------
    InputError
        Not a number or ratio, or not positive and finite (named ``--fs``).
    """
    if isinstance(text, (int, float)):
        v = float(text)
    else:
        try:
            if "/" in text:
                a, b = text.split("/", 1)
                v = float(a) / float(b)
            else:
                v = float(text)
        except (ValueError, ZeroDivisionError):
            raise InputError(f"not a sample rate: {text!r} (a number of Hz or a ratio a/b)",
                             "--fs") from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"sample rate must be positive and finite, got {text!r}", "--fs")
    return v


def split_names(text: str | list[str] | None) -> list[str] | None:
    """``"a, b"`` -> ``["a", "b"]``; a list is returned as is; None stays None."""
    if text is None or isinstance(text, list):
        return text
    return [c.strip() for c in text.split(",") if c.strip()]


def parse_range(text: str | None, what: str = "--range") -> slice | None:
    """``"START:STOP"`` (Python slice of sample indices, either end may be empty) -> slice.

    Raises
    ------
    InputError
        Not of the form ``START:STOP`` with integers (named ``what``).
    """
    if not text:
        return None
    try:
        a, b = text.split(":")
        return slice(int(a) if a.strip() else None, int(b) if b.strip() else None)
    except ValueError:
        raise InputError(f"{what} must look like START:STOP, got {text!r}", what) from None


def apply_range(record: Record, rng: str | slice | None) -> Record:
    """``record`` restricted to the samples ``rng`` (``"START:STOP"`` or a slice).

    Raises
    ------
    InputError
        A malformed range, or one that selects no sample.
    """
    if not rng:
        return record
    s = parse_range(rng) if isinstance(rng, str) else rng
    out = record.slice(s.start, s.stop)
    if out.n == 0:
        text = rng if isinstance(rng, str) else f"{s.start or ''}:{s.stop or ''}"
        raise InputError(f"--range {text} selects no samples of {record.n}", "--range")
    return out


def load(path: str | Path, *, fs: str | float | None = None,
         inputs: str | list[str] | None = None, outputs: str | list[str] | None = None,
         range: str | slice | None = None,  # noqa: A002 - the CLI's name
         var: str | None = None, time_column: str | int | None = None) -> Record:
    """Load a record: an HDF5 recording, an interchange CSV, a plain CSV or a MATLAB file.

    Parameters
    ----------
    path : path
        ``.h5`` recording of ``rigd experiment``/``rigd run --record``, interchange CSV
        (``../shared/data-format.md``), or a plain CSV (header row + numbers, with ``fs``).
    fs : float or str, optional
        Sample rate of a plain CSV without metadata, Hz (number or ratio such as
        ``"10000000/16384"``). Given: the file is read as a plain CSV.
    inputs, outputs : list of str or comma-separated str, optional
        Input (excitation) and output (response) columns of a plain CSV.
    range : str or slice, optional
        Use only samples ``START:STOP`` (e.g. ``"40000:"``).
    var, time_column : str, optional
        MATLAB ``.mat`` files (v5 or v7.3): the matrix holding the samples and its 1-based
        time column (else ``fs``); ``inputs``/``outputs`` are then 1-based columns (``"2:4"``)
        or names of variables of the file (:mod:`rigd.data.matio`).

    Returns
    -------
    Record
        Columns in SI-like units of the interchange format (µm, V, rad), ``fs`` in Hz, and
        ``meta`` (operating point Ω in rpm and P_I in bar, ``kind``, ``source``...).

    Raises
    ------
    InputError
        Missing or malformed file, ``inputs``/``outputs`` without ``fs``, a bad range.
    """
    from rigd.data.io import load_record
    from rigd.data.matio import is_mat

    if is_mat(path):
        rec = load_record(path, fs=None if fs is None else parse_fs(fs), inputs=inputs,
                          outputs=outputs, var=var, time_column=time_column)
        return apply_range(rec, range)
    if var is not None or time_column is not None:
        raise InputError("--var/--time-column apply to MATLAB .mat files only", str(path))
    if fs is None:
        if inputs or outputs:
            raise InputError("--inputs/--outputs are for plain CSV files and need --fs")
        rec = load_record(path)
    else:
        rec = load_record(path, fs=parse_fs(fs), inputs=split_names(inputs),
                          outputs=split_names(outputs))
    return apply_range(rec, range)


def as_record(data: Record | str | Path, **kw: Any) -> Record:
    """``data`` itself if it is a Record (``range`` still applied), else :func:`load` it."""
    if isinstance(data, Record):
        return apply_range(data, kw.get("range"))
    return load(data, **kw)


def describe_source(meta: dict[str, Any]) -> dict[str, Any]:
    """Where a record or run came from, as its metadata says.

    Parameters
    ----------
    meta : dict
        A record's ``meta`` or a ``manifest.json``.

    Returns
    -------
    dict
        ``{"source": "simulated" | "rig" | None, "drivers": {"fast": name, "slow": [names]}
        | None}``; ``None`` when the file does not say (records from elsewhere, or made
        before rigd wrote it).
    """
    src = meta.get("source")
    drivers = meta.get("drivers")
    return {"source": src if src in SOURCES else None,
            "drivers": drivers if isinstance(drivers, dict) else None}


def source_text(info: dict[str, Any]) -> str:
    """One line for humans: ``source: simulated (drivers: fast sim)``."""
    if info.get("source") is None:
        return "source: not stated by the record (not written by rigd's recorder)"
    d = info.get("drivers") or {}
    names = [f"fast {d['fast']}"] if d.get("fast") else []
    names += [f"slow {s}" for s in d.get("slow") or []]
    return f"source: {info['source']}" + (f" (drivers: {', '.join(names)})" if names else "")
