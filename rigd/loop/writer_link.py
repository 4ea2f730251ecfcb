"""The loop's side of the writer process (:mod:`rigd.recording.writer`, spawned by name).

HDF5 files are written outside the loop's process: h5py holds the interpreter lock while it
writes a chunk, and the 5 kHz loop thread must share its lock with nothing that slow. The
:class:`WriterLink` spawns the writer (a fresh interpreter, not a fork: nothing of the loop's
threads or locks is copied) with the ring's handle, opens and closes files through it
(:class:`rigd.loop.sinks.FileSink` proxies, each given a sink slot in the ring's header),
forwards fault events, and reads its replies in a thread of its own. The writer's consumer
index is the header's ``H_RD``; the recorder frees ring rows only up to it while the link
is :attr:`ready`.

If the writer process dies, the receiving thread sees the end of its connection at once:
every open recording is failed with one line naming the file, the writer's end (signal or
exit status) and what the file keeps (``on_error``: the loop latches ``recorder_overflow``),
and the recorder stops waiting for it (the loop cycles on; the next recording spawns a new
writer).
"""

from __future__ import annotations

import multiprocessing
import signal
import threading
import time

from rigd.loop.clock import boost_threads
from rigd.loop.shared_ring import H_RD, N_SINK_SLOTS, SharedRing
from rigd.loop.sinks import FileSink, file_failure
from rigd.spawn import call

#: bound on waiting for the writer's start and answers, s: only a hung writer reaches it (a
#: spawned interpreter importing h5py took tens of seconds on the shared machine at load 25)
WRITER_WAIT_S = 600.0


class RecordingFailed(OSError):
    """A recording could not be written (disk full, file too large, I/O error, the writer
    process died).

    The message names the file, the reason and what the file still holds (the frames up to its
    last successful flush); ``cause`` is the original exception, if any; ``path`` the file,
    ``n_flushed`` the frames on disk (at its last flush), ``open_ended`` whether it was an
    open-ended recording (``rigd run --record``) rather than a segment's.
    """

    def __init__(self, message: str, cause: BaseException | None = None, *,
                 path: str | None = None, n_flushed: int | None = None,
                 open_ended: bool = False):
        super().__init__(message)
        self.cause = cause
        self.path = path
        self.n_flushed = n_flushed
        self.open_ended = open_ended


def how_ended(code: int | None) -> str:
    """How a child process ended, from its exit code (None, a status, a negative signal)."""
    if code is None:
        return "its connection closed"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


class WriterLink:
    """One writer process and its connection (see module docstring).

    Parameters
    ----------
    shared : SharedRing
        The ring (must be shared: :meth:`SharedRing.handle` not None).
    flush_interval_s : float
        The writer's flush period, s.
    on_error : callable
        ``on_error(RecordingFailed)`` when a recording fails (the loop latches a fault).
    on_change : callable
        ``on_change()`` after anything that may free ring rows or end a wait.
    priority : callable, optional
        ``priority()``: the real-time helper priority while the loop thread runs real-time
        (None: ordinary). The receiving thread takes it at its start: holding the
        interpreter lock, an ordinary thread preempted by another process would stall the
        loop thread (priority inversion).
    """

    def __init__(self, shared: SharedRing, flush_interval_s: float, on_error, on_change,
                 priority=None) -> None:
        handle = shared.handle()
        if handle is None:
            raise RecordingFailed(f"recording refused: {shared.unshared}; the writer process "
                                  f"cannot map a private ring")
        self.hdr = shared.hdr
        self._on_error, self._on_change = on_error, on_change
        ctx = multiprocessing.get_context("spawn")
        here, there = ctx.Pipe(duplex=True)
        # named by module: the loop's process never imports the writer nor h5py (import
        # contract, pyproject.toml)
        self.proc = ctx.Process(target=call, name="rigd-writer", daemon=True,
                                args=("rigd.recording.writer", "main", handle, there,
                                      float(flush_interval_s)))
        self.proc.start()
        there.close()
        self._conn = here
        self._send_lock = threading.Lock()
        self._lock = threading.Lock()
        self.sinks: dict[int, FileSink] = {}
        self._opened: dict[int, tuple[threading.Event, list]] = {}
        #: the writer has mapped the ring and published its consumer index
        self.ready = threading.Event()
        #: the writer process has ended (its connection closed)
        self.gone = threading.Event()
        self.pid: int | None = None
        self._priority = priority
        self._thread = threading.Thread(target=self._receive, name="rigd-writer-link",
                                        daemon=True)
        self._thread.start()

    @property
    def consumed(self) -> int:
        """The writer's consumer index (frames, total)."""
        return int(self.hdr[H_RD])

    @property
    def native_id(self) -> int | None:
        return self._thread.native_id

    def wait_ready(self, timeout: float = WRITER_WAIT_S) -> None:
        """Block until the writer runs (RecordingFailed if it died or hung first)."""
        end = time.monotonic() + timeout
        while not self.ready.wait(0.05):
            if self.gone.is_set() or time.monotonic() > end:
                how = (how_ended(self.proc.exitcode) if self.gone.is_set()
                       else f"no answer within {timeout:g} s")
                raise RecordingFailed(f"recording refused: the writer process did not start "
                                      f"({how})")

    # --- requests (any thread) -----------------------------------------------------------
    def _send(self, msg: tuple) -> bool:
        with self._send_lock:
            try:
                self._conn.send(msg)
                return True
            except (OSError, ValueError):
                return False

    def open(self, sink: FileSink) -> None:
        """Create ``sink``'s file in the writer; RecordingFailed when it could not."""
        self.wait_ready()
        with self._lock:
            free = [i for i in range(N_SINK_SLOTS) if i not in self.sinks]
            if not free:
                raise RecordingFailed(f"recording {sink.path} refused: {N_SINK_SLOTS} "
                                      f"recordings are open already")
            slot = free[0]
            sink.attach(self.hdr, slot)
            self.sinks[slot] = sink
            answer: list = []
            ev = threading.Event()
            self._opened[slot] = (ev, answer)
        if not self._send(("open", slot, sink.spec())):
            ev.set()
        try:
            while not ev.wait(0.05):
                if self.gone.is_set():
                    break
        except BaseException:
            # interrupted (SIGINT) while the writer creates the file: nobody will finish this
            # sink, so it is closed here at once (nothing recorded), not held open by the
            # writer until the loop closes
            sink.closing = True
            self.close(sink)
            raise
        with self._lock:
            self._opened.pop(slot, None)
        if answer and answer[0] is None:
            return
        self._drop(slot)
        why = answer[0] if answer else (f"recording {sink.path} refused: the writer process "
                                        f"ended ({how_ended(self.proc.exitcode)})")
        raise RecordingFailed(why)

    def close(self, sink: FileSink) -> None:
        """Ask the writer to close ``sink`` after its ``last_seq`` (set by the caller)."""
        if sink.slot < 0 or not self._send(("close", sink.slot)):
            self._fail_one(sink, None)

    def event(self, seq: int, code: int, text: str) -> None:
        self._send(("event", seq, code, text))

    def stop(self, timeout: float = 30.0) -> None:
        """Close every file (after what is published), end the process."""
        self._send(("stop",))
        self.gone.wait(timeout)
        self.proc.join(5.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(5.0)
        try:
            self._conn.close()
        except OSError:
            pass

    # --- replies (the receiving thread) --------------------------------------------------
    def _drop(self, slot: int) -> FileSink | None:
        with self._lock:
            sink = self.sinks.pop(slot, None)
        if sink is not None:
            sink.detach()
        self._on_change()
        return sink

    def _receive(self) -> None:
        prio = self._priority() if self._priority is not None else None
        if prio is not None:
            boost_threads([threading.get_native_id()], prio)
        try:
            while True:
                msg = self._conn.recv()
                kind = msg[0]
                if kind == "ready":
                    self.pid = int(msg[1])
                    self.ready.set()
                elif kind == "opened":
                    with self._lock:
                        waiting = self._opened.get(msg[1])
                    if waiting is not None:
                        waiting[1].append(msg[2])
                        waiting[0].set()
                elif kind == "flushed":
                    s = self.sinks.get(msg[1])
                    if s is not None:
                        s.n_flushed = int(msg[2])
                elif kind == "closed":
                    _, slot, n_written, n_flushed, err = msg
                    s = self._drop(slot)
                    if s is not None:
                        s.n_written, s.n_flushed = int(n_written), int(n_flushed)
                        if err is not None:
                            self._fail_one(s, err)
                        s.done.set()
                elif kind == "failed":
                    s = self._drop(msg[1])
                    if s is not None:
                        s.n_flushed = int(msg[3])
                        self._fail_one(s, msg[2])
                elif kind == "stopped":
                    break
        except (EOFError, OSError):
            pass
        self.proc.join(5.0)
        how = how_ended(self.proc.exitcode)
        with self._lock:
            left = list(self.sinks.values())
        for s in left:
            self._drop(s.slot)
            self._fail_one(s, None, how)
        self.gone.set()
        self._on_change()

    def _fail_one(self, sink: FileSink, line: str | None, how: str | None = None) -> None:
        """Fail ``sink`` loudly: its error, the loop's fault (``on_error``), its waiter."""
        if line is None:
            line = file_failure(sink, f"the writer process ended ({how or 'unknown'})")
        sink.failure = line
        exc = RecordingFailed(line, path=str(sink.path), n_flushed=sink.n_flushed,
                              open_ended=sink.n_expected <= 0)
        sink.error = exc
        self._on_error(exc)        # the fault is requested before the waiter learns of it
        sink.done.set()
