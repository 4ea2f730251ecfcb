"""Export a record to the interchange CSV, streaming: memory stays bounded by one row block.

* HDF5 recording -> CSV: the frames are read and written ``block_rows`` rows at a time.
* CSV (interchange or plain, with ``fs``) or MATLAB .mat -> CSV: the record is read (strictly)
  and re-written.

Every file is written atomically (temporary file + rename): on any error no output appears.
Numbers use the shortest round-trip ``repr``, so the CSV reads back bit-for-bit.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from rigd.data import csvio, h5io
from rigd.data.record import invalid_samples_error
from rigd.errors import InputError
from rigd.fileio import atomic_open

BLOCK_ROWS = 16384


def _check_out(src: Path, out: Path) -> None:
    try:
        if out.exists() and out.resolve() == src.resolve():
            raise InputError("output is the input file; choose another path", str(out))
    except OSError:
        pass
    if out.is_dir():
        raise InputError("output is a directory", str(out))
    if os.path.lexists(out):
        raise InputError("exists: an export never overwrites a file; choose a new name",
                         str(out))


def export_csv(src: str | Path, out: str | Path, *, columns: list[str] | None = None,
               block_rows: int = BLOCK_ROWS, mat: dict[str, Any] | None = None,
               rng: slice | None = None) -> int:
    """Write the record at ``src`` (HDF5, CSV or MATLAB .mat) to ``out`` as an interchange
    CSV.

    Parameters
    ----------
    src, out : path
    columns : list of str, optional
        Only these channels (``t`` is always written first if the record has it).
    block_rows : int
        Rows per block: the memory bound.
    mat : dict, optional
        A MATLAB file's options (``var``, ``inputs``, ``outputs``, ``time_column``, ``fs``:
        :func:`rigd.data.matio.read_mat`).
    rng : slice, optional
        Only these samples (``--range``). A recording with invalid samples (NaN: docs/data.md,
        "Invalid samples") in the exported columns is refused naming its first invalid
        stretch and the longest valid one: the interchange CSV holds valid samples only.

    Returns
    -------
    int
        Rows written.
    """
    src, out = Path(src), Path(out)
    if not src.exists():
        raise InputError("no such file", str(src))
    _check_out(src, out)
    if h5io.is_hdf5(src):
        with h5io.open_recording(src) as rec:
            names = list(rec.names)
            if columns:
                missing = [c for c in columns if c not in names]
                if missing:
                    raise InputError(f"no channel(s) {', '.join(missing)} in the recording "
                                     f"(has: {', '.join(names)})", str(src))
                wanted = list(columns)
                if "t" in names and "t" not in wanted:
                    wanted.insert(0, "t")
            else:
                wanted = list(names)
            if "t" in wanted:
                wanted.remove("t")
                wanted.insert(0, "t")
            idx = [names.index(c) for c in wanted]
            start, stop, _ = (rng or slice(None)).indices(rec.n)
            if stop <= start:
                raise InputError(f"--range selects no sample of the {rec.n}", str(src))
            _refuse_invalid(rec, wanted, idx, start, stop, block_rows, str(src))
            meta: dict[str, Any] = {k: v for k, v in rec.meta.items() if k != "units"}
            meta.setdefault("omega_rpm", 0.0)
            with atomic_open(out, "w", replace=False, encoding="utf-8", newline="\n") as fh:
                return csvio.write_blocks(fh, rec.fs, meta, wanted,
                                          rec.blocks(block_rows, idx, start, stop), str(src))
    from rigd.data.io import load_record

    record = load_record(src, **(mat or {}))
    if rng is not None:
        record = record.slice(rng.start, rng.stop)
    if columns:
        record = _select(record, columns)
    record.check_finite(list(record.columns), "the export (choose --columns to leave it out)")
    return csvio.write_csv(out, record, block_rows=block_rows, replace=False)


def _refuse_invalid(rec, names, idx, start, stop, block_rows, source) -> None:
    """Refuse (one line) exported samples ``start:stop`` of a recording holding NaN."""
    bad = np.zeros(stop - start, dtype=bool)
    first = None
    at = 0
    for block in rec.blocks(block_rows, idx, start, stop):
        b = ~np.isfinite(block)
        if b.any() and first is None:
            first = names[int(np.flatnonzero(b.any(axis=0))[0])]
        bad[at:at + len(block)] = b.any(axis=1)
        at += len(block)
    if first is not None:
        raise invalid_samples_error(bad, rec.fs, start, first, "the export", source)


def convert_raw_csv(src: str | Path, out: str | Path, *, fs: float,
                    inputs: list[str] | None = None, outputs: list[str] | None = None,
                    meta: dict[str, Any] | None = None) -> int:
    """Convert a plain CSV (no rig-data metadata) into an interchange CSV; returns rows."""
    from rigd.data.rawcsv import read_raw_csv

    src, out = Path(src), Path(out)
    _check_out(src, out)
    record = read_raw_csv(src, fs=fs, inputs=inputs, outputs=outputs, meta=meta)
    record.check_finite(list(record.columns), "the conversion")
    return csvio.write_csv(out, record, replace=False)


def _select(record, columns):
    from rigd.data.record import Record

    missing = [c for c in columns if c not in record.columns]
    if missing:
        raise InputError(f"no column(s) {', '.join(missing)} in the record", record.source)
    keep = (["t"] if "t" in record.columns and "t" not in columns else []) + list(columns)
    return Record({c: record.columns[c] for c in keep}, record.fs, dict(record.meta),
                  record.source, record.lines, record.first_sample, record.bad_cells)
