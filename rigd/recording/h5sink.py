"""An HDF5 recording in SWMR mode: written by the writer process only (:mod:`.writer`).

Layout (``docs/ARCHITECTURE.md``, ``../shared/data-format.md``): ``/frames`` float64
(N, N_REC) with ``channels``/``units``, root attributes (``fs``, ``omega_rpm``,
``p_inj_bar``, ``kind``, ``config``, ``rigd_version``, ``created`` and the recording's
metadata), ``/events`` (``seq``, ``code``, ``text``); flushed periodically so that a file
whose writer was killed is readable up to the last flush (:func:`open_recording`,
``swmr=True``).

Completeness, in root attributes: ``complete`` (bool), ``incomplete_reason`` (str, "" when
complete) and ``n_frames`` (frames on disk). A file is created ``complete = False`` with
:data:`NOT_CLOSED` as the reason, ``n_frames`` is updated at every flush, and only a close
after every expected frame sets ``complete = True``: a file whose writer was killed, or
that a full disk froze, says so by itself. The file is created, never opened over an
existing one (mode ``"x"``: a record is never truncated).

This module imports h5py: the loop's process never imports it (import contract,
``pyproject.toml``); the loop hands recordings to the writer process as
:class:`rigd.loop.sinks.FileSink` proxies.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rigd import __version__
from rigd.frame import N_REC, RECORD_NAMES, RECORD_UNITS
from rigd.loop.sinks import EVENT_TEXT_LEN, Sink, file_failure, reason

#: the reason a file says it is incomplete until its writer closes it
NOT_CLOSED = ("not closed by its writer: the writing process ended (killed, or the disk "
              "filled) before the recording's end; frames up to the last flush are kept")


class H5Sink(Sink):
    """An HDF5 recording in SWMR mode (see module docstring)."""

    def __init__(self, path: str | Path, *, fs: float, meta: dict[str, Any] | None = None,
                 config_text: str = "", chunk_frames: int = 4096, n_expected: int = 0) -> None:
        super().__init__()
        self.path = Path(path)
        self.n_expected = int(n_expected)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        meta = dict(meta or {})
        # "x": fails if the file exists (FileExistsError): never truncates a record
        f = h5py.File(self.path, "x", libver="latest")
        try:
            ds = f.create_dataset("frames", shape=(0, N_REC), maxshape=(None, N_REC),
                                  dtype="f8", chunks=(chunk_frames, N_REC))
            ds.attrs["channels"] = np.array(RECORD_NAMES, dtype=h5py.string_dtype())
            ds.attrs["units"] = np.array(RECORD_UNITS, dtype=h5py.string_dtype())
            ev = f.create_group("events")
            for name, dt in (("seq", "i8"), ("code", "i8"), ("text", f"S{EVENT_TEXT_LEN}")):
                ev.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dt, chunks=(256,))
            attrs = {"fs": float(fs), "omega_rpm": 0.0, "p_inj_bar": float("nan"),
                     "kind": "run", "config": config_text, "rigd_version": __version__,
                     "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
            attrs.update(meta)
            attrs.update(complete=False, incomplete_reason=NOT_CLOSED, n_frames=np.int64(0))
            for k, v in attrs.items():
                f.attrs[k] = _attr_value(v)
            f.swmr_mode = True
        except BaseException:
            f.close()
            raise
        self._f = f
        self._ds = ds
        self._ev = ev

    def write(self, block: np.ndarray) -> None:
        n0 = self._ds.shape[0]
        self._ds.resize(n0 + len(block), axis=0)
        self._ds[n0:] = block
        self.n_written = n0 + len(block)

    def event(self, seq: int, code: int, text: str) -> None:
        n = self._ev["seq"].shape[0]
        for name in ("seq", "code", "text"):
            self._ev[name].resize(n + 1, axis=0)
        self._ev["seq"][n] = seq
        self._ev["code"][n] = code
        self._ev["text"][n] = text.encode("utf-8")[:EVENT_TEXT_LEN]

    def flush(self) -> None:
        n = self._ds.shape[0]
        self._ds.flush()
        for name in ("seq", "code", "text"):
            self._ev[name].flush()
        self._f.attrs.modify("n_frames", np.int64(n))   # in place: same type and shape
        self._f.flush()
        self.n_flushed = n

    def describe_failure(self, exc: BaseException) -> str:
        return file_failure(self, reason(exc))

    def close(self, why: str | None = None) -> None:
        """Mark the file complete or not (``why``: the reason it is not; fewer frames than
        expected also make it incomplete), flush and close it."""
        n = self._ds.shape[0]
        if why is None and n < self.n_expected:
            why = f"ended early: {n} of {self.n_expected} frames recorded"
        try:
            self._f.attrs["complete"] = why is None
            self._f.attrs["incomplete_reason"] = why or ""
            self.flush()
        except BaseException:
            self.abandon()   # a failed final flush: keep the file as last flushed (see below)
            raise
        self._f.close()

    def abandon(self) -> None:
        """After a failed write (disk full, I/O error): freeze the file as it is on disk.

        The file was flushed in SWMR mode, so what is on disk is consistent up to the last
        flush. Any further write by the HDF5 library (cache eviction, the close) could leave
        metadata pointing past the end of the file, so the file descriptor is pointed at
        /dev/null before the h5py file is closed.
        """
        if not self._f.id.valid:
            return
        try:
            fd = self._f.id.get_vfd_handle()
            null = os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(null, fd)
            finally:
                os.close(null)
        except Exception:  # noqa: BLE001 - best effort; the error is already reported
            pass
        try:
            self._f.close()
        except Exception:  # noqa: BLE001
            pass


def _attr_value(v: Any):
    if v is None:
        return "null"
    if isinstance(v, (bool, int, float, str, np.integer, np.floating)):
        return v
    if isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
        return np.asarray(v, dtype=float)
    return json.dumps(v, default=str)


def open_recording(path: str | Path):
    """Open a recording for reading (SWMR-aware: works on a live or crashed file).

    Returns an ``h5py.File``; the caller closes it.
    """
    return h5py.File(path, "r", libver="latest", swmr=True)
