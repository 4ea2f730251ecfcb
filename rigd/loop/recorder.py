"""Recorder: preallocated ring buffer -> writer thread -> HDF5 (h5py, chunked, SWMR).

The cycle kernel writes one frame per cycle into ``ring`` (float64 (ring_n, N_REC)) at row
``w % ring_n`` and never waits. The loop *publishes* the total written count ``w`` after each
kernel call; the writer thread copies published frames to every active *sink* (an HDF5 file or
an in-memory array) whose sequence range covers them, then frees the rows by advancing the read
count ``st[S_RD]`` that the kernel checks. A full ring is never a silent drop: lock-step waits
for the writer, the real-time cycle counts the frame in ``st[S_DROPPED]`` and latches
RECORDER_OVERFLOW.

HDF5 layout (docs/ARCHITECTURE.md): ``/frames`` float64 (N, N_REC), chunked, resizable,
attributes ``channels`` and ``units``; root attributes ``fs``, ``omega_rpm``, ``p_inj_bar``,
``kind``, ``config``, ``rigd_version``, ``created`` and any extra metadata; ``/events/seq``,
``/events/code``, ``/events/text`` (faults and markers). The file is written in SWMR mode and
flushed every ``flush_interval_s``: after a crash (even SIGKILL) it is readable up to the last
flush. Open such a file with :func:`open_recording` (``swmr=True``).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigd import __version__
from rigd.frame import N_REC, RECORD_NAMES, RECORD_UNITS, REC
from rigd.loop.layout import S_RD

_SEQ = REC["seq"]
EVENT_TEXT_LEN = 120


@dataclass
class RecordSpec:
    """Where and with which metadata to record (``run_segment(record=...)``).

    ``meta`` goes into the file's root attributes (``kind``, ``experiment``, ``omega_rpm``...).
    """

    path: str | Path
    meta: dict[str, Any] = field(default_factory=dict)


class RecordingFailed(OSError):
    """A recording could not be written (disk full, file too large, I/O error).

    The message names the file, the reason and what the file still holds (the frames up to its
    last successful flush); ``cause`` is the original exception.
    """

    def __init__(self, message: str, cause: BaseException | None = None):
        super().__init__(message)
        self.cause = cause


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
                f"rigd.loop.recorder.open_recording (h5py swmr=True)")

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


class Recorder:
    """Owns the ring buffer and the writer thread.

    Parameters
    ----------
    ring_frames : int
        Ring capacity, frames.
    st : numpy.ndarray
        The loop's state array (the writer advances ``st[S_RD]``).
    flush_interval_s : float
        HDF5 flush period.
    on_error : callable, optional
        ``on_error(exc)`` when a sink fails (the loop latches a fault).
    """

    def __init__(self, ring_frames: int, st: np.ndarray, *, flush_interval_s: float = 0.5,
                 on_error=None) -> None:
        self.ring = np.zeros((ring_frames, N_REC))
        self.n = ring_frames
        self._st = st
        self.published = 0                 # frames the loop has published (total)
        self.read = int(st[S_RD])          # frames consumed (total)
        self.flush_interval_s = flush_interval_s
        self._sinks: list[Sink] = []
        self._pending_events: list[tuple[int, int, str]] = []
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._freed = threading.Condition()
        self._stop = False
        self._on_error = on_error
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    # --- lifecycle -------------------------------------------------------------------
    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="rigd-recorder", daemon=True)
            self._thread.start()

    def close(self, timeout: float = 30.0) -> None:
        """Write what is published, close every sink, stop the thread."""
        self.drain(timeout)
        self._stop = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        with self._lock:
            sinks, self._sinks = self._sinks, []
        for s in sinks:
            self._close_sink(s)

    # --- loop side -------------------------------------------------------------------
    def publish(self, w: int) -> None:
        """The loop has written frames up to total count ``w`` (called after a kernel call)."""
        self.published = w
        if w - self.read >= self.n // 4:
            self._wake.set()

    def wait_free(self, timeout: float = 10.0) -> None:
        """Block until the writer frees rows (lock-step only; never on the real-time path)."""
        self._wake.set()
        with self._freed:
            self._freed.wait_for(lambda: self.published - self.read < self.n or self._stop,
                                 timeout)

    def drain(self, timeout: float = 30.0) -> None:
        """Block until every published frame has been handed to the sinks."""
        if self._thread is None:
            self._consume()
            return
        self._wake.set()
        with self._freed:
            self._freed.wait_for(lambda: self.read >= self.published, timeout)

    def add_sink(self, sink: Sink) -> Sink:
        with self._lock:
            self._sinks.append(sink)
        return sink

    def finish(self, sink: Sink, last_seq: int | None = None, timeout: float = 60.0) -> None:
        """End ``sink`` after ``last_seq`` (default: what is published), wait until closed."""
        if last_seq is None:
            last_seq = self.published - 1 if sink.first_seq is not None else -1
        sink.last_seq = last_seq
        sink.closing = True
        self._wake.set()
        if self._thread is None:
            self._consume()
        if not sink.done.wait(timeout):
            raise TimeoutError(f"recorder did not finish {sink} within {timeout} s")
        if sink.error is not None:
            raise sink.error

    def add_event(self, seq: int, code: int, text: str) -> None:
        """Record a fault or marker in every open file covering ``seq``."""
        with self._lock:
            self._pending_events.append((int(seq), int(code), str(text)))
        self._wake.set()

    # --- writer thread ---------------------------------------------------------------
    def _run(self) -> None:
        last_flush = time.monotonic()
        while not self._stop:
            self._wake.wait(0.02)
            self._wake.clear()
            self._consume()
            now = time.monotonic()
            if now - last_flush >= self.flush_interval_s:
                last_flush = now
                for s in list(self._sinks):
                    self._guard(s, s.flush)
        self._consume()

    def _guard(self, sink: Sink, fn, *args) -> None:
        try:
            fn(*args)
        except BaseException as exc:  # disk full, permission...: loud, never silent
            sink.abandon()
            exc = RecordingFailed(sink.describe_failure(exc), exc)
            sink.error = exc
            self.error = exc
            with self._lock:
                if sink in self._sinks:
                    self._sinks.remove(sink)
            sink.done.set()
            if self._on_error is not None:
                self._on_error(exc)

    def _consume(self) -> None:
        pub = self.published
        rd = self.read
        with self._lock:
            sinks = list(self._sinks)
            events, self._pending_events = self._pending_events, []
        while rd < pub:
            a = rd % self.n
            m = min(pub - rd, self.n - a, 65536)
            block = self.ring[a:a + m]
            s0 = int(block[0, _SEQ])
            s1 = int(block[-1, _SEQ])
            for s in sinks:
                if s.first_seq is None or s.error is not None:
                    continue
                lo = max(s.first_seq, s0)
                hi = s1 if s.last_seq is None else min(s.last_seq, s1)
                if lo <= hi:
                    self._guard(s, s.write, block[lo - s0:hi - s0 + 1])
                    s.last_written_seq = hi
            rd += m
            self.read = rd
            self._st[S_RD] = rd
            with self._freed:
                self._freed.notify_all()
        for seq, code, text in events:
            for s in sinks:
                if s.first_seq is not None and seq >= s.first_seq and \
                        (s.last_seq is None or seq <= s.last_seq):
                    self._guard(s, s.event, seq, code, text)
        for s in sinks:
            if s.closing and s.last_seq is not None and s.error is None and \
                    (s.last_seq < (s.first_seq or 0) or rd > s.last_seq or
                     (s.last_written_seq is not None and s.last_written_seq >= s.last_seq)):
                self._close_sink(s)
        with self._freed:
            self._freed.notify_all()

    def _close_sink(self, s: Sink) -> None:
        with self._lock:
            if s in self._sinks:
                self._sinks.remove(s)
        if not s.done.is_set():
            try:
                s.close()
            except BaseException as exc:
                s.error = RecordingFailed(s.describe_failure(exc), exc)
                self.error = s.error
                if self._on_error is not None:
                    self._on_error(s.error)
            s.done.set()
