"""The runs folder for the console: run directories with their manifests, and records
decimated server-side (min/max per bucket) so that a long record opens fast and zooms."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from rigd.data import h5io
from rigd.data.io import load_record
from rigd.data.manifest import MANIFEST, read_manifest
from rigd.errors import InputError
from rigd.web.files import UPLOADS, walk

#: record files the console opens (HDF5 recordings and interchange CSV)
RECORD_SUFFIXES = (".h5", ".hdf5", ".csv")
#: at most this many run directories and files per run are listed
MAX_LIST = 2000
#: largest manifest.json read, bytes
MAX_MANIFEST = 8 << 20
#: largest CSV record opened (read whole), bytes; HDF5 recordings are read in blocks
MAX_CSV = 256 << 20


def _duration_s(man: dict[str, Any]) -> float | None:
    try:
        t0 = datetime.fromisoformat(str(man["started"]).replace("Z", "+00:00"))
        t1 = datetime.fromisoformat(str(man["finished"]).replace("Z", "+00:00"))
    except (KeyError, TypeError, ValueError):
        return None
    return (t1 - t0).total_seconds()


def _operating_point(man: dict[str, Any]) -> dict[str, Any] | None:
    op = (man.get("experiment") or {}).get("operating_point")
    if isinstance(op, dict):
        return {"omega_rpm": op.get("omega_rpm"), "p_inj_bar": op.get("p_inj_bar")}
    pts = man.get("points") or []
    if pts and isinstance(pts[0], dict):
        return {"omega_rpm": pts[0].get("omega_rpm"), "p_inj_bar": pts[0].get("p_inj_bar")}
    return None


def _files(run: Path, suffixes: tuple[str, ...]) -> list[str]:
    """Files of a run with one of ``suffixes`` (relative paths; symlinks not followed)."""
    return [p.relative_to(run).as_posix() for p in walk(run, suffixes, MAX_LIST)]


def summarize(run: Path) -> dict[str, Any]:
    """One run directory: name, kind, operating point, source, duration (s), status, its
    record files and HTML pages (relative paths), ``incomplete`` (the records its manifest
    lists as cut short); ``error`` when the manifest is unreadable."""
    entry: dict[str, Any] = {"name": run.name, "records": _files(run, RECORD_SUFFIXES),
                             "pages": _files(run, (".html",))}
    try:
        st = (run / MANIFEST).lstat()
    except OSError:
        entry["error"] = "no manifest.json"
        return entry
    if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_MANIFEST:
        entry["error"] = f"manifest.json is not a regular file of at most {MAX_MANIFEST} bytes"
        return entry
    try:
        man = read_manifest(run)
    except InputError as exc:
        entry["error"] = str(exc)
        return entry
    exp = man.get("experiment") or {}
    entry.update(kind=exp.get("kind"), experiment=exp.get("name"),
                 operating_point=_operating_point(man), source=man.get("source"),
                 duration_s=_duration_s(man), status=man.get("status"),
                 started=man.get("started"), points=len(man.get("points") or []),
                 message=man.get("message") or "",
                 incomplete=[f.get("path") for f in man.get("files") or []
                             if isinstance(f, dict) and f.get("complete") is False])
    return entry


def list_runs(runs_dir: str | Path) -> list[dict[str, Any]]:
    """Every sub-folder of the runs folder (newest name first), summarised; symlinks,
    dot-names and the folder of kept uploads are not listed."""
    root = Path(runs_dir)
    if not root.is_dir():
        return []
    with os.scandir(root) as it:
        dirs = sorted((Path(e.path) for e in it if e.is_dir(follow_symlinks=False)
                       and not e.name.startswith(".") and e.name != UPLOADS),
                      key=lambda p: p.name, reverse=True)
    return [summarize(p) for p in dirs[:MAX_LIST]]


def minmax(x: np.ndarray, buckets: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Min/max decimation: ``(first_index, min, max)`` of ``buckets`` equal slices of ``x``.

    Every sample lies in exactly one bucket, so no peak is lost however long the record;
    with ``len(x) <= buckets`` each sample is its own bucket (min = max = x).
    """
    n = len(x)
    if n == 0:
        return np.zeros(0, int), np.zeros(0), np.zeros(0)
    buckets = max(1, min(int(buckets), n))
    edges = (np.arange(buckets + 1) * n) // buckets
    starts = edges[:-1]
    return starts, np.minimum.reduceat(x, starts), np.maximum.reduceat(x, starts)


def minmax_blocks(blocks: Iterable[tuple[int, np.ndarray]], start: int, stop: int,
                  buckets: int, ncols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`minmax` of rows ``[start, stop)`` of a record read in row blocks (bounded
    memory: a long HDF5 recording is never loaded whole).

    Parameters
    ----------
    blocks : iterable of (first_row, array (rows, ncols))
        Consecutive row blocks covering ``[start, stop)`` (rows outside are ignored).
    start, stop : int
        Row window.
    buckets : int
        Buckets wanted (at most ``stop - start``).
    ncols : int

    Returns
    -------
    (first_row, min, max)
        ``first_row`` (B,), ``min``/``max`` (B, ncols); the same buckets as :func:`minmax`.
    """
    n = stop - start
    b = max(1, min(int(buckets), n))
    edges = start + (np.arange(b + 1) * n) // b
    lo = np.full((b, ncols), np.inf)
    hi = np.full((b, ncols), -np.inf)
    for b0, block in blocks:
        s0, s1 = max(b0, start), min(b0 + len(block), stop)
        if s0 >= s1:
            continue
        part = block[s0 - b0:s1 - b0]
        first = int(np.searchsorted(edges, s0, "right")) - 1
        last = int(np.searchsorted(edges, s1 - 1, "right")) - 1
        ids = np.arange(first, last + 1)
        local = np.maximum(edges[ids], s0) - s0
        lo[ids] = np.fmin(lo[ids], np.minimum.reduceat(part, local, axis=0))
        hi[ids] = np.fmax(hi[ids], np.maximum.reduceat(part, local, axis=0))
    lo[np.isinf(lo) & (lo > 0)] = np.nan      # a bucket of only NaN samples
    hi[np.isinf(hi) & (hi < 0)] = np.nan
    return edges[:-1], lo, hi


#: rows read at a time from an HDF5 recording
BLOCK_ROWS = 65536


def _window(n: int, fs: float, t0: float | None, t1: float | None, path) -> tuple[int, int]:
    start = 0 if t0 is None else int(np.clip(np.floor(t0 * fs), 0, n))
    stop = n if t1 is None else int(np.clip(np.ceil(t1 * fs) + 1, 0, n))
    if stop - start < 1:
        raise InputError(f"empty window t0={t0} t1={t1} (record {n / fs:.6g} s)", str(path))
    return start, stop


def _pick(available: list[str], channels: list[str] | None, path) -> list[str]:
    names = channels or [c for c in available if c != "t"]
    unknown = [c for c in names if c not in available]
    if unknown:
        raise InputError(f"no channel {unknown[0]!r} (has {', '.join(available)})", str(path))
    return names


def record_view(path: str | Path, points: int = 2000, t0: float | None = None,
                t1: float | None = None, channels: list[str] | None = None) -> dict[str, Any]:
    """A record (or its ``[t0, t1]`` s window) decimated to at most ``points`` min/max pairs
    per channel, for zoomable traces. An HDF5 recording is read in row blocks (memory bounded
    by the block, whatever the record's length); a CSV file is read whole.

    Returns
    -------
    dict
        ``fs_hz``, ``n`` (samples in the record), ``start``/``stop`` (sample window),
        ``t_s`` (time of each bucket's first sample, s), ``channels``:
        name -> ``{"min": [...], "max": [...]}``, ``units``, ``decimated`` (bool).

    Raises
    ------
    InputError
        Unreadable record, unknown channel, empty window.
    """
    points = int(np.clip(points, 10, 20000))
    if h5io.is_hdf5(path):
        with h5io.open_recording(path) as rec:
            n, fs = rec.n, rec.fs
            start, stop = _window(n, fs, t0, t1, path)
            names = _pick(rec.names, channels, path)
            cols = [rec.names.index(c) for c in names]
            units = {c: u for c, u in zip(rec.names, rec.units) if c in names}
            blocks = ((s, np.asarray(rec.frames[s:min(s + BLOCK_ROWS, stop)],
                                     dtype=np.float64)[:, cols])
                      for s in range(start, stop, BLOCK_ROWS))
            idx, lo, hi = minmax_blocks(blocks, start, stop, points, len(cols))
    else:
        if Path(path).stat().st_size > MAX_CSV:
            raise InputError(f"CSV record over {MAX_CSV >> 20} MiB: not opened here", str(path))
        rec = load_record(path)
        n, fs = rec.n, rec.fs
        start, stop = _window(n, fs, t0, t1, path)
        names = _pick(list(rec.columns), channels, path)
        data = np.column_stack([np.asarray(rec.columns[c], float) for c in names])
        idx, lo, hi = minmax_blocks([(0, data)], start, stop, points, len(names))
        units = {c: u for c, u in (rec.meta.get("units") or {}).items() if c in names}
    out = {c: {"min": _finite_list(lo[:, k]), "max": _finite_list(hi[:, k])}
           for k, c in enumerate(names)}
    return {"fs_hz": fs, "n": n, "start": start, "stop": stop,
            "t_s": [float(v) for v in idx / fs], "channels": out, "units": units,
            "decimated": stop - start > points}


def _finite_list(a: np.ndarray) -> list[float | None]:
    return [float(v) if np.isfinite(v) else None for v in a]
