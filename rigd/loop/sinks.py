"""Recording sinks: where the recorder's writer thread puts frames and events.

:class:`Sink` (a destination of a contiguous sequence range), :class:`MemorySink` (frames in
memory) and :class:`H5Sink` (an HDF5 file in SWMR mode, layout in ``docs/ARCHITECTURE.md``:
``/frames`` float64 (N, N_REC) with ``channels``/``units``, root attributes, ``/events``;
flushed periodically so a crashed file is readable up to the last flush), :class:`RecordSpec`
(where and with which metadata a loop records) and :func:`open_recording` to read such a file.
Used by :class:`rigd.loop.recorder.Recorder`.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigd import __version__
from rigd.frame import N_REC, RECORD_NAMES, RECORD_UNITS

EVENT_TEXT_LEN = 120


@dataclass
class RecordSpec:
    """Where and with which metadata to record (``run_segment(record=...)``).

    ``meta`` goes into the file's root attributes (``kind``, ``experiment``, ``omega_rpm``...).
    """

    path: str | Path
    meta: dict[str, Any] = field(default_factory=dict)


def _reason(exc: BaseException) -> str:
    """Short reason of a failed write: the OS error text when it can be found."""
    errno_ = getattr(exc, "errno", None)
    if not isinstance(errno_, int):
        m = re.search(r"errno = (\d+)", str(exc))
        errno_ = int(m.group(1)) if m else None
    if isinstance(errno_, int) and errno_ > 0:
        return f"{os.strerror(errno_)} (errno {errno_})"
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:200]


class Sink:
    """Destination of a contiguous range of frames ``[first_seq, last_seq]`` (inclusive).

    ``first_seq`` may be set later (by the loop thread, at the cycle boundary where recording
    starts); ``last_seq`` None means open-ended until :meth:`Recorder.finish`.
    """

    def __init__(self) -> None:
        self.first_seq: int | None = None
        self.last_seq: int | None = None
        self.n_written = 0
        self.error: BaseException | None = None
        self.done = threading.Event()
        self.closing = False
        self.last_written_seq: int | None = None
        self.n_flushed = 0                 # frames safely on disk (at the last good flush)

    def describe_failure(self, exc: BaseException) -> str:
        """One line: what failed and what the destination still holds."""
        return f"recording failed: {_reason(exc)}"

    # called by the writer thread only
    def write(self, block: np.ndarray) -> None:
        raise NotImplementedError

    def event(self, seq: int, code: int, text: str) -> None:
        pass

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass

    def abandon(self) -> None:
        """Give up after a failed write: keep what is on disk, never write again."""


class MemorySink(Sink):
    """Frames kept in memory (for :func:`rigd.loop.sim.simulate_record`)."""

    def __init__(self, n_expected: int = 0) -> None:
        super().__init__()
        self._buf = np.empty((max(n_expected, 1), N_REC))
        self.events: list[tuple[int, int, str]] = []

    def write(self, block: np.ndarray) -> None:
        n = self.n_written + len(block)
        if n > len(self._buf):
            new = np.empty((max(n, 2 * len(self._buf)), N_REC))
            new[:self.n_written] = self._buf[:self.n_written]
            self._buf = new
        self._buf[self.n_written:n] = block
        self.n_written = n

    def event(self, seq: int, code: int, text: str) -> None:
        self.events.append((seq, code, text))

    @property
    def frames(self) -> np.ndarray:
        return self._buf[:self.n_written]


class H5Sink(Sink):
    """An HDF5 recording in SWMR mode (see module docstring)."""

    def __init__(self, path: str | Path, *, fs: float, meta: dict[str, Any] | None = None,
                 config_text: str = "", chunk_frames: int = 4096) -> None:
        import h5py

        super().__init__()
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        meta = dict(meta or {})
        f = h5py.File(self.path, "w", libver="latest")
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
        self._f.flush()
        self.n_flushed = n

    def describe_failure(self, exc: BaseException) -> str:
        n = self.n_flushed
        kept = (f"the file keeps every frame up to the last flush ({n} frames, seq "
                f"{self.first_seq}..{self.first_seq + n - 1})" if n and self.first_seq is not None
                else "no frame had been flushed to it")
        return (f"recording {self.path} failed: {_reason(exc)}; {kept}, readable with "
                f"rigd.loop.sinks.open_recording (h5py swmr=True)")

    def close(self) -> None:
        try:
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


def make_sink(record, n_expected: int, *, fs: float, config, config_text: str,
              last_frame: np.ndarray | None, controller) -> Sink:
    """The sink for ``record`` ("memory", a path or a :class:`RecordSpec`) of a loop.

    The file's metadata: ``kind`` run, the operating point (the last frame's Ω and P_I when
    finite, else the config's ``plant`` section), the controller's source, then ``spec.meta``.
    """
    if isinstance(record, str) and record == "memory":
        return MemorySink(n_expected)
    from rigd.frame import REC

    spec = record if isinstance(record, RecordSpec) else RecordSpec(record)
    plant = config.plant or {}
    meta: dict[str, Any] = {"kind": "run", "omega_rpm": plant.get("omega_rpm", 0.0),
                            "p_inj_bar": plant.get("p_inj_bar", float("nan"))}
    for key in ("omega_rpm", "p_inj_bar"):
        if last_frame is not None and np.isfinite(last_frame[REC[key]]):
            meta[key] = float(last_frame[REC[key]])
    if controller is not None:
        meta["controller"] = str(controller.source)
    meta.update(spec.meta)
    return H5Sink(spec.path, fs=fs, meta=meta, config_text=config_text,
                  chunk_frames=config.recorder.chunk_frames)


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
    import h5py

    return h5py.File(path, "r", libver="latest", swmr=True)
