"""Reader of the project's HDF5 recordings (layout in docs/ARCHITECTURE.md).

* dataset ``/frames``: float64 (N, C), attribute ``channels`` (names) and ``units``;
* root attributes ``fs``, ``omega_rpm``, ``p_inj_bar``, ``kind`` and any other metadata;
* group ``/events`` (optional): ``seq``, ``code``, ``text``.

A file whose writer crashed reads up to the last flush: the file is opened in SWMR read mode
(or without file locking), and trailing rows that were allocated but never written (all zero)
are dropped. :func:`open_recording` gives streaming access in row blocks (bounded memory,
used by the CSV export); :func:`read_h5` reads the whole record into memory.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigd.data.record import Record
from rigd.errors import InputError
from rigd.plain import plain

HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"


def is_hdf5(path: str | Path) -> bool:
    """True if the file starts with the HDF5 signature."""
    try:
        with open(path, "rb") as fh:
            return fh.read(8) == HDF5_MAGIC
    except OSError:
        return False


def _decode_attr(v: Any) -> Any:
    """Undo the recorder's attribute encoding: ``"null"`` -> None, JSON lists/dicts."""
    if v == "null":
        return None
    if isinstance(v, str) and v[:1] in "[{":
        import json

        try:
            return json.loads(v)
        except ValueError:
            return v
    return v


@dataclass
class Recording:
    """An open HDF5 recording: channel names, metadata and the frames dataset."""

    path: str
    names: list[str]
    units: list[str]
    fs: float
    meta: dict[str, Any]
    frames: Any          #: the h5py dataset (N, C)
    n: int               #: number of valid (flushed) rows

    def blocks(self, rows: int = 65536, columns: list[int] | None = None,
               start: int = 0, stop: int | None = None) -> Iterator[np.ndarray]:
        """Yield float64 row blocks of at most ``rows`` rows (bounded memory) of the frames
        ``start:stop``."""
        end = self.n if stop is None else min(stop, self.n)
        for s in range(max(0, start), end, rows):
            block = self.frames[s:min(s + rows, end)]
            if columns is not None:
                block = block[:, columns]
            yield np.asarray(block, dtype=np.float64)


def _open(path: str):
    import h5py

    errors = []
    for kwargs in ({"swmr": True}, {"locking": False}, {}):
        try:
            return h5py.File(path, "r", **kwargs)
        except (OSError, TypeError, ValueError) as exc:
            errors.append(exc)
    raise InputError(f"cannot open as HDF5: {str(errors[-1]).splitlines()[0]}", path)


def _valid_rows(frames, n: int) -> int:
    """Drop trailing rows that are entirely zero (allocated, never written before a crash)."""
    step = 4096
    end = n
    while end > 1:
        s = max(end - step, 1)
        block = np.asarray(frames[s:end])
        nz = np.flatnonzero(np.any(block != 0, axis=1))
        if nz.size:
            return s + int(nz[-1]) + 1
        end = s
    return min(n, 1)


@contextmanager
def open_recording(path: str | Path) -> Iterator[Recording]:
    """Open an HDF5 recording for streaming reads.

    Raises
    ------
    InputError
        Not HDF5, no ``/frames`` dataset, no ``channels`` attribute, bad shape, no ``fs``.
    """
    spath = str(path)
    if not Path(spath).exists():
        raise InputError("no such file", spath)
    f = _open(spath)
    try:
        if "frames" not in f:
            raise InputError("not a rigd recording: no /frames dataset", spath)
        ds = f["frames"]
        if ds.ndim != 2:
            raise InputError(f"/frames must be 2-D (N, C), has shape {ds.shape}", spath)
        if "channels" not in ds.attrs:
            raise InputError("/frames has no 'channels' attribute (channel names)", spath)
        names = [str(n) for n in plain(ds.attrs["channels"])]
        if len(names) != ds.shape[1]:
            raise InputError(f"/frames has {ds.shape[1]} columns but {len(names)} channel "
                             "names", spath)
        if len(set(names)) != len(names):
            raise InputError("duplicate channel names in /frames", spath)
        units = [str(u) for u in plain(ds.attrs.get("units", [""] * len(names)))]
        meta = {k: _decode_attr(plain(v)) for k, v in f.attrs.items()}
        for k in ("omega_rpm", "p_inj_bar"):
            v = meta.get(k)
            if isinstance(v, float) and not np.isfinite(v):
                del meta[k]          # the recorder writes NaN for "not known"
        if "fs" not in meta:
            raise InputError("no 'fs' attribute (sample rate) on the file", spath)
        try:
            fs = float(meta.pop("fs"))
        except (TypeError, ValueError):
            raise InputError("attribute 'fs' is not a number", spath) from None
        if not (np.isfinite(fs) and fs > 0):
            raise InputError(f"attribute fs must be a positive number, got {fs!r}", spath)
        meta["units"] = dict(zip(names, units))
        try:
            ds.refresh()  # SWMR: see the writer's last flush
        except Exception:  # noqa: BLE001 - not SWMR / not supported
            pass
        n = _valid_rows(ds, int(ds.shape[0]))
        yield Recording(spath, names, units, fs, meta, ds, n)
    finally:
        f.close()


def read_events(path: str | Path) -> list[dict[str, Any]]:
    """The ``/events`` group as a list of ``{"seq", "code", "text"}`` (empty if none)."""
    spath = str(path)
    f = _open(spath)
    try:
        if "events" not in f:
            return []
        g = f["events"]
        seq = plain(g["seq"][()]) if "seq" in g else []
        code = plain(g["code"][()]) if "code" in g else [None] * len(seq)
        text = plain(g["text"][()]) if "text" in g else [""] * len(seq)
        return [{"seq": s, "code": c, "text": t} for s, c, t in zip(seq, code, text)]
    finally:
        f.close()


def read_h5(path: str | Path) -> Record:
    """Read a whole HDF5 recording into a :class:`Record` (columns by channel name)."""
    with open_recording(path) as rec:
        data = np.asarray(rec.frames[:rec.n], dtype=np.float64)
        columns = {n: np.ascontiguousarray(data[:, i]) for i, n in enumerate(rec.names)}
        meta = dict(rec.meta)
        if rec.n < rec.frames.shape[0]:
            meta["truncated_rows"] = int(rec.frames.shape[0] - rec.n)
        if "seq" in columns and rec.n > 1:
            gaps = int(np.count_nonzero(np.diff(columns["seq"]) != 1))
            if gaps:
                meta["seq_gaps"] = gaps
        return Record(columns, rec.fs, meta, rec.path)


def write_h5(path: str | Path, record: Record, *, chunk_rows: int = 4096,
             replace: bool = True) -> None:
    """Write a :class:`Record` as a recording in the project's HDF5 layout (atomically).

    Used to bring CSV data into the recording format and by tests/benchmarks; the loop's
    recorder writes the same layout incrementally (SWMR).
    """
    import h5py

    from rigd.fileio import atomic_open

    names = list(record.columns)
    units = record.meta.get("units") or {}
    with atomic_open(path, "wb", replace=replace) as fh, \
            h5py.File(fh, "w", libver="latest") as f:
        n = record.n
        ds = f.create_dataset("frames", shape=(n, len(names)), maxshape=(None, len(names)),
                              dtype="f8", chunks=(max(1, min(chunk_rows, n or 1)),
                                                  len(names)))
        for s in range(0, n, 65536):
            ds[s:s + 65536] = np.column_stack([record.columns[k][s:s + 65536]
                                               for k in names])
        ds.attrs["channels"] = np.array(names, dtype=h5py.string_dtype())
        ds.attrs["units"] = np.array([str(units.get(k, "")) for k in names],
                                     dtype=h5py.string_dtype())
        f.attrs["fs"] = float(record.fs)
        for k, v in record.meta.items():
            if k == "units" or v is None:
                continue
            if isinstance(v, (list, tuple)) and all(isinstance(x, str) for x in v):
                v = np.array(v, dtype=h5py.string_dtype())
            elif isinstance(v, dict):
                import json
                v = json.dumps(v)
            f.attrs[k] = v
