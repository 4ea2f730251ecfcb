"""Recorder: preallocated ring buffer in shared memory -> memory sinks here, HDF5 files in the
writer process.

The cycle kernel writes one frame per cycle into ``ring`` (float64 (ring_n, N_REC)) at row
``w % ring_n`` and never waits. The loop *publishes* the total written count ``w`` after each
kernel call. Two consumers read the published frames:

* the **keeper thread** here copies them to the in-memory sinks (:class:`MemorySink`,
  ``simulate_record``) and frees ring rows by advancing the read count ``st[S_RD]`` that the
  kernel checks;
* the **writer process** (:mod:`rigd.recording.writer`, spawned on the first file recording
  through :class:`~rigd.loop.writer_link.WriterLink`) writes HDF5 files and publishes its own
  consumer index in the ring's header (``H_RD``). While it runs, ``st[S_RD]`` never passes it.

A full ring is never a silent drop: lock-step waits for the consumers, the real-time cycle
counts the frame in ``st[S_DROPPED]`` and latches RECORDER_OVERFLOW. A recording the writer
could not write, or whose writer process died, fails loudly (:class:`RecordingFailed`, the
``on_error`` callback: the loop latches RECORDER_OVERFLOW too).

HDF5 layout: :mod:`rigd.recording.h5sink` (docs/ARCHITECTURE.md). This process never imports
h5py (import contract).
"""

from __future__ import annotations

import datetime as _dt
import threading
from typing import Any

import numpy as np

from rigd.frame import N_REC, REC
from rigd.loop.layout import S_RD
from rigd.loop.shared_ring import SharedRing
from rigd.loop.sinks import FileSink, Sink
from rigd.loop.writer_link import RecordingFailed, WriterLink

__all__ = ["Recorder", "RecordingFailed"]

_SEQ = REC["seq"]


class Recorder:
    """Owns the ring buffer, the keeper thread and the link to the writer process.

    Parameters
    ----------
    ring_frames : int
        Ring capacity, frames.
    st : numpy.ndarray
        The loop's state array (the keeper thread advances ``st[S_RD]``).
    flush_interval_s : float
        HDF5 flush period (the writer process's), s.
    on_error : callable, optional
        ``on_error(exc)`` when a recording fails (the loop latches a fault).
    fs : float
        Loop rate, Hz (told to the ring's readers).
    """

    def __init__(self, ring_frames: int, st: np.ndarray, *, flush_interval_s: float = 0.5,
                 on_error=None, fs: float = 0.0) -> None:
        #: the ring lives in shared memory so that the daemon's socket process can read recent
        #: frames for the live stream (read-only) and the writer process can write them to
        #: HDF5, never through the loop thread
        self.shared = SharedRing(ring_frames, N_REC, fs)
        self.ring = self.shared.ring
        self._share = self.shared.publish
        self.n = ring_frames
        self._st = st
        self.published = 0                 # frames the loop has published (total)
        self.read = int(st[S_RD])          # frames freed for the kernel (total)
        self._mem_read = self.read         # frames the keeper has handed to memory sinks
        self.flush_interval_s = flush_interval_s
        self._sinks: list[Sink] = []       # memory sinks (the keeper's)
        self._pending_events: list[tuple[int, int, str]] = []
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._freed = threading.Condition()
        self._waiting = 0
        self._stop = False
        self._on_error = on_error
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None
        #: the writer process's link (None until the first file recording, or after it died)
        self.writer: WriterLink | None = None
        self._writer_lock = threading.Lock()
        #: ``helper_priority()``: the real-time helper priority while the loop runs (the
        #: writer link's thread takes it; set by the loop)
        self.helper_priority = None
        #: the last recording failure (``why``, ``since``, ``path``, ``open_ended``), kept
        #: until a new recording opens — for ever after an open-ended one (``rigd run
        #: --record``): that recording is dead whatever a fault reset says
        self.failure: dict[str, Any] | None = None

    # --- lifecycle -------------------------------------------------------------------
    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="rigd-recorder", daemon=True)
            self._thread.start()

    @property
    def native_id(self) -> int | None:
        """Kernel thread id of the keeper thread (None before :meth:`start`)."""
        return self._thread.native_id if self._thread is not None else None

    @property
    def link_native_id(self) -> int | None:
        """Kernel thread id of the writer link's receiving thread (None: no writer)."""
        w = self.writer
        return w.native_id if w is not None else None

    @property
    def writer_pid(self) -> int | None:
        """The writer process's pid (None when none runs)."""
        w = self.writer
        return w.pid if w is not None and not w.gone.is_set() else None

    def close(self, timeout: float = 30.0) -> None:
        """Write what is published, close every sink and file, stop the thread and the writer."""
        self.drain(timeout)
        w = self.writer
        if w is not None:
            for s in list(w.sinks.values()):
                if s.last_seq is None:
                    s.last_seq = self.published - 1
                w.close(s)
            w.stop(timeout)
            self.writer = None
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
        """The loop has written frames up to total count ``w`` (called after a kernel call).

        Runs in: loop thread — O(1), allocation-free, non-blocking (sets an event at most;
        :meth:`SharedRing.publish` stores ``w`` and the wall time for the other processes).
        """
        self.published = w
        self._share(w)
        if w - self.read >= self.n // 4:
            self._wake.set()

    def wait_free(self, timeout: float = 10.0) -> None:
        """Block until the consumers free rows (lock-step only; never on the real-time path)."""
        self._wait(lambda: self.published - self.read < self.n or self._stop, timeout)

    def drain(self, timeout: float = 30.0) -> None:
        """Block until every published frame has been handed to the sinks and the writer."""
        if self._thread is None:
            self._consume()
            return
        self._wait(lambda: self.read >= self.published or self._stop, timeout)

    def _wait(self, pred, timeout: float) -> None:
        with self._freed:
            self._waiting += 1
        self._wake.set()
        try:
            with self._freed:
                self._freed.wait_for(pred, timeout)
        finally:
            with self._freed:
                self._waiting -= 1

    def add_sink(self, sink: Sink) -> Sink:
        """Add a memory sink, or open a file sink in the writer process (spawned on the first
        one; RecordingFailed when the file cannot be created or no writer can run)."""
        if isinstance(sink, FileSink):
            self._writer().open(sink)
            f = self.failure
            if f is not None and not f["open_ended"]:
                self.failure = None        # recording works again
            return sink
        with self._lock:
            self._sinks.append(sink)
        return sink

    def _writer(self) -> WriterLink:
        with self._writer_lock:
            w = self.writer
            if w is None or w.gone.is_set():
                w = WriterLink(self.shared, self.flush_interval_s, self._failed, self._changed,
                               self.helper_priority)
                self.writer = w
        w.wait_ready()
        self._wake.set()
        return w

    def finish(self, sink: Sink, last_seq: int | None = None, timeout: float = 60.0) -> None:
        """End ``sink`` after ``last_seq`` (default: what is published), wait until closed."""
        if last_seq is None:
            last_seq = self.published - 1 if sink.first_seq is not None else -1
        sink.last_seq = last_seq
        sink.closing = True
        if isinstance(sink, FileSink):
            if not sink.done.is_set():
                w = self.writer
                if w is None:
                    raise RecordingFailed(f"recording {sink.path}: no writer process holds it")
                w.close(sink)
        else:
            self._wake.set()
            if self._thread is None:
                self._consume()
        if not sink.done.wait(timeout):
            raise TimeoutError(f"recorder did not finish {sink} within {timeout} s")
        if sink.error is not None:
            raise sink.error

    def add_event(self, seq: int, code: int, text: str) -> None:
        """Record a fault or marker in every open recording covering ``seq``."""
        with self._lock:
            self._pending_events.append((int(seq), int(code), str(text)))
        w = self.writer
        if w is not None:
            w.event(seq, code, text)
        self._wake.set()

    # --- keeper thread ---------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """The recorder's state for ``status``: ``state`` (``recording``: a file is open;
        ``failed``: see ``failure``; ``idle``), ``files`` (open recordings) and ``failure``
        (``why`` one line, ``since`` UTC ISO time, ``path``, ``open_ended``) or None."""
        w = self.writer
        files = ([str(s.path) for s in list(w.sinks.values())]
                 if w is not None and not w.gone.is_set() else [])
        f = self.failure
        state = "failed" if f is not None else "recording" if files else "idle"
        return {"state": state, "files": files, "failure": dict(f) if f else None}

    def _failed(self, exc: BaseException) -> None:
        self.failure = {"why": str(exc).splitlines()[0] if str(exc) else type(exc).__name__,
                        "since": _dt.datetime.now(_dt.timezone.utc).isoformat(
                            timespec="seconds"),
                        "path": getattr(exc, "path", None),
                        "open_ended": bool(getattr(exc, "open_ended", False))}
        self.error = exc
        if self._on_error is not None:
            self._on_error(exc)

    def _changed(self) -> None:
        self._wake.set()

    def _run(self) -> None:
        while not self._stop:
            # 1 ms while someone waits for the writer process to free rows, else 20 ms
            self._wake.wait(0.001 if self._waiting else 0.02)
            self._wake.clear()
            self._consume()
        self._consume()

    def _guard(self, sink: Sink, fn, *args) -> None:
        try:
            fn(*args)
        except BaseException as exc:  # loud, never silent
            sink.abandon()
            exc = RecordingFailed(sink.describe_failure(exc), exc)
            sink.error = exc
            with self._lock:
                if sink in self._sinks:
                    self._sinks.remove(sink)
            self._failed(exc)        # the fault is requested before the waiter learns of it
            sink.done.set()

    def _consume(self) -> None:
        pub = self.published
        rd = self._mem_read
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
        self._mem_read = rd
        w = self.writer
        if w is not None and w.ready.is_set() and not w.gone.is_set():
            rd = min(rd, w.consumed)        # never free what the writer has not written
        if rd > self.read:
            self.read = rd
            self._st[S_RD] = rd
        for seq, code, text in events:
            for s in sinks:
                if s.first_seq is not None and seq >= s.first_seq and \
                        (s.last_seq is None or seq <= s.last_seq):
                    self._guard(s, s.event, seq, code, text)
        for s in sinks:
            if s.closing and s.last_seq is not None and s.error is None and \
                    (s.last_seq < (s.first_seq or 0) or self._mem_read > s.last_seq or
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
                self._failed(s.error)
            s.done.set()
