"""The writer process: the loop's recorded frames from the shared ring into HDF5 files.

Spawned by the loop's recorder (:class:`rigd.loop.writer_link.WriterLink`, by module name:
the loop's process never imports this module nor h5py), with the ring's handle
(:class:`rigd.loop.shared_ring.RingHandle`) and one duplex connection. It maps the ring
read-write but writes only its consumer index ``H_RD`` (frames it has consumed, total):
the loop's recorder frees ring rows up to it, so a writer that is slow or stopped makes the
ring fill, and the cycle then counts every frame it cannot store (``recorder.dropped``) and
latches ``recorder_overflow`` — never a silent loss. A writer that dies is seen by the
loop's process at once (end of file on the connection): its open recordings are reported
failed, with what each file keeps (the frames up to its last flush).

Messages (tuples) from the loop's process:

* ``("open", slot, spec)`` — create the file (:class:`rigd.recording.h5sink.H5Sink`, ``spec``
  from :meth:`rigd.loop.sinks.FileSink.spec`); answered ``("opened", slot, error)``
  (``error`` one line, or None). Its range is read from sink slot ``slot`` of the ring's
  header (``first_seq``, ``last_seq``), *after* the published count: the loop sets
  ``first_seq`` before the first frame of the range is published.
* ``("close", slot)`` — close it once every frame up to its ``last_seq`` is written;
  answered ``("closed", slot, n_written, n_flushed, error)``.
* ``("event", seq, code, text)`` — a fault or marker, into every open file covering ``seq``.
* ``("stop",)`` — write what is published, close every file, answer ``("stopped",)``, exit.

And to it: ``("ready", pid)`` once the ring is mapped; ``("flushed", slot, n_flushed)``
after each periodic flush; ``("failed", slot, line)`` when a file could not be written
(disk full: the file is frozen as last flushed, :meth:`H5Sink.abandon`). If the loop's
process goes away (end of file), every file is flushed and closed and the process exits.
"""

from __future__ import annotations

import os
import signal
import time

from rigd.frame import REC
from rigd.loop.shared_ring import H_RD, H_SINKS, H_W, OPEN_END, RingHandle, RingReader
from rigd.loop.sinks import reason
from rigd.recording.h5sink import H5Sink

_SEQ = REC["seq"]
#: why a file closed after the loop's process went away is incomplete
ORPHANED = ("the loop's process (rigd run or rigd experiment) ended before the recording's "
            "end; every frame it had published is kept")
_BLOCK = 65536              # frames handed to h5py at once, at most
_IDLE_S = 0.01              # wait for a message this long when no frame is new


class Writer:
    """The writer's state: the ring, the open files, what is pending (see module docstring)."""

    def __init__(self, handle: RingHandle, conn, flush_interval_s: float) -> None:
        self.ring = RingReader(handle, writable=True)
        self.hdr, self.frames, self.n = self.ring.hdr, self.ring.ring, self.ring.n
        self.conn = conn
        self.flush_interval_s = float(flush_interval_s)
        self.sinks: dict[int, H5Sink] = {}
        self.closing: set[int] = set()
        self.events: list[tuple[int, int, str]] = []
        # nothing before this instant is asked of it: recordings open after "ready"
        self.rd = int(self.hdr[H_W])
        self.hdr[H_RD] = self.rd
        self.stopping = False
        #: the loop's process went away (end of file on the connection)
        self.orphaned = False

    # --- messages ----------------------------------------------------------------------
    def handle(self, msg: tuple) -> None:
        kind = msg[0]
        if kind == "open":
            _, slot, spec = msg
            try:
                sink = H5Sink(spec["path"], fs=spec["fs"], meta=spec["meta"],
                              config_text=spec["config_text"],
                              chunk_frames=spec["chunk_frames"],
                              n_expected=spec.get("n_expected", 0))
            except FileExistsError as exc:
                # EEXIST also comes when a folder on the path is a file: only a file that is
                # there is "refused: it exists"
                msg = (f"recording {spec['path']}: refused: the file exists (a record is "
                       "never overwritten)" if os.path.lexists(spec["path"]) else
                       f"recording {spec['path']}: cannot create it: {reason(exc)}")
                self.conn.send(("opened", slot, msg))
                return
            except Exception as exc:  # noqa: BLE001 - told to the loop's process, one line
                self.conn.send(("opened", slot,
                                f"recording {spec['path']}: cannot create it: {reason(exc)}"))
                return
            self.sinks[slot] = sink
            self.conn.send(("opened", slot, None))
        elif kind == "close":
            self.closing.add(msg[1])
        elif kind == "event":
            self.events.append((int(msg[1]), int(msg[2]), str(msg[3])))
        elif kind == "stop":
            self.stopping = True

    def _ranges(self) -> None:
        """Each open file's range from its sink slot (read after the published count)."""
        hdr = self.hdr
        for slot, s in self.sinks.items():
            i = H_SINKS + 2 * slot
            first, last = int(hdr[i]), int(hdr[i + 1])
            s.first_seq = None if first < 0 else first
            s.last_seq = None if last >= OPEN_END else last

    # --- frames ----------------------------------------------------------------------
    def consume(self, pub: int) -> None:
        """Write frames ``[rd, pub)`` to the files whose range covers them; free them."""
        rd, n, frames = self.rd, self.n, self.frames
        while rd < pub:
            a = rd % n
            m = min(pub - rd, n - a, _BLOCK)
            block = frames[a:a + m]
            s0, s1 = int(block[0, _SEQ]), int(block[-1, _SEQ])
            for slot, s in list(self.sinks.items()):
                if s.first_seq is None:
                    continue
                lo = max(s.first_seq, s0)
                hi = s1 if s.last_seq is None else min(s.last_seq, s1)
                if lo <= hi and self._guard(slot, s.write, block[lo - s0:hi - s0 + 1]):
                    s.last_written_seq = hi
            rd += m
            self.rd = rd
            self.hdr[H_RD] = rd          # the loop frees these rows
        events, self.events = self.events, []
        for seq, code, text in events:
            for slot, s in list(self.sinks.items()):
                if s.first_seq is not None and seq >= s.first_seq and \
                        (s.last_seq is None or seq <= s.last_seq):
                    self._guard(slot, s.event, seq, code, text)

    def finish_closing(self, everything: bool = False) -> None:
        """Close the files asked to close whose last frame is written (all: ``everything``;
        :attr:`orphaned`: each is marked incomplete, the loop's process having gone)."""
        for slot in list(self.closing if not everything else self.sinks):
            s = self.sinks.get(slot)
            if s is None:
                self.closing.discard(slot)
                continue
            last = s.last_seq
            if not everything and last is not None and s.first_seq is not None and \
                    last >= s.first_seq and self.rd <= last and \
                    (s.last_written_seq is None or s.last_written_seq < last):
                continue                    # frames of its range still to come
            del self.sinks[slot]
            self.closing.discard(slot)
            err = None
            try:
                s.close(ORPHANED if self.orphaned else None)
            except Exception as exc:  # noqa: BLE001 - reported, one line
                err = s.describe_failure(exc)
            self.conn.send(("closed", slot, s.n_written, s.n_flushed, err))

    def flush(self) -> None:
        for slot, s in list(self.sinks.items()):
            if self._guard(slot, s.flush):
                self.conn.send(("flushed", slot, s.n_flushed))

    def _guard(self, slot: int, fn, *args) -> bool:
        """Run a write; on failure freeze the file, tell the loop's process, drop the sink."""
        try:
            fn(*args)
            return True
        except Exception as exc:  # noqa: BLE001 - disk full, I/O error: loud, never silent
            s = self.sinks.pop(slot)
            self.closing.discard(slot)
            s.abandon()
            self.conn.send(("failed", slot, s.describe_failure(exc), s.n_flushed))
            return False

    # --- the process ---------------------------------------------------------------------
    def run(self) -> None:
        self.conn.send(("ready", os.getpid()))
        last_flush = time.monotonic()
        while True:
            pub = int(self.hdr[H_W])          # first: see the slots' ordering above
            wait = 0.0 if pub > self.rd else _IDLE_S
            try:
                while self.conn.poll(wait):
                    wait = 0.0
                    self.handle(self.conn.recv())
            except (EOFError, OSError):       # the loop's process is gone: keep the files
                self.stopping = True
                self.orphaned = True
                self.conn = _Gone()
            self._ranges()
            self.consume(pub)
            if self.stopping:
                self.consume(int(self.hdr[H_W]))
                self.finish_closing(everything=True)
                self.conn.send(("stopped",))
                return
            self.finish_closing()
            now = time.monotonic()
            if now - last_flush >= self.flush_interval_s:
                last_flush = now
                self.flush()


class _Gone:
    """The connection after the loop's process went away: replies go nowhere."""

    def send(self, _msg) -> None:
        pass


def main(handle: RingHandle, conn, flush_interval_s: float) -> None:
    """The writer process's entry (spawned by name: ``rigd.recording.writer``, ``main``).

    A write beyond a file-size limit fails (EFBIG, reported) instead of killing the process
    (SIGXFSZ ignored); Ctrl-C at a terminal stops the daemon, which then stops this process
    after closing the files (SIGINT ignored here).
    """
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    Writer(handle, conn, flush_interval_s).run()
