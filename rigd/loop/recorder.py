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

The sinks (:class:`~rigd.loop.sinks.H5Sink`, :class:`~rigd.loop.sinks.MemorySink`), the
:class:`~rigd.loop.sinks.RecordSpec` and :func:`~rigd.loop.sinks.open_recording` live in
:mod:`rigd.loop.sinks`.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from rigd.frame import N_REC, REC
from rigd.loop.layout import S_RD
from rigd.loop.shared_ring import SharedRing
from rigd.loop.sinks import Sink

_SEQ = REC["seq"]


class RecordingFailed(OSError):
    """A recording could not be written (disk full, file too large, I/O error).

    The message names the file, the reason and what the file still holds (the frames up to its
    last successful flush); ``cause`` is the original exception.
    """

    def __init__(self, message: str, cause: BaseException | None = None):
        super().__init__(message)
        self.cause = cause


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
    fs : float
        Loop rate, Hz (told to the ring's readers).
    """

    def __init__(self, ring_frames: int, st: np.ndarray, *, flush_interval_s: float = 0.5,
                 on_error=None, fs: float = 0.0) -> None:
        #: the ring lives in shared memory so that the daemon's socket process can read recent
        #: frames for the live stream (read-only, never through the loop thread)
        self.shared = SharedRing(ring_frames, N_REC, fs)
        self.ring = self.shared.ring
        self._share = self.shared.publish
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

    @property
    def native_id(self) -> int | None:
        """Kernel thread id of the writer thread (None before :meth:`start`)."""
        return self._thread.native_id if self._thread is not None else None

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
        """The loop has written frames up to total count ``w`` (called after a kernel call).

        Runs in: loop thread — O(1), allocation-free, non-blocking (sets an event at most;
        :meth:`SharedRing.publish` stores ``w`` and the wall time for the stream readers).
        """
        self.published = w
        self._share(w)
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
            if self._on_error is not None:   # the fault is requested before anyone waiting
                self._on_error(exc)          # on the sink learns of the failure
            sink.done.set()

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
