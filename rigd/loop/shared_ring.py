"""The recorder's ring buffer in shared memory, and a read-only reader for other processes.

The cycle kernel writes one record frame per cycle into the ring (float64 ``(n, N_REC)``, row
``w % n``); the recorder *publishes* the total written count ``w`` after each kernel call
(:meth:`rigd.loop.recorder.Recorder.publish`). Here the ring and a small header live in one
anonymous shared-memory file (``memfd_create``: no name in ``/dev/shm``, nothing left behind
when the daemon dies, whatever the signal), so that the daemon's **socket process** can map
it **read-only** (``PROT_READ``, reopened ``O_RDONLY``) and read recent frames for the live
stream (``stream.subscribe``) without the loop thread doing anything for it.

Header (int64 slots before the ring, :data:`HDR_SLOTS` of them):

=========  ===========================================================================
``H_W``      frames published (total; the newest is frame ``w - 1``)
``H_WALL``   ``time.time_ns()`` when ``w`` was published (stored before ``H_W``, see
             :meth:`SharedRing.publish`)
``H_N``      ring capacity, frames
``H_COLS``   columns per frame
``H_AHEAD``  how many frames the kernel may write beyond the published count (lock-step
             batch; 1 on the real-time clock)
``H_MAGIC``  :data:`MAGIC` (layout version)
``H_FS``     loop rate, mHz
``H_RD``     frames consumed by the **writer process** (total; written by it only,
             :mod:`rigd.recording.writer`): the loop's recorder frees ring rows up to it
``H_SINKS``  :data:`N_SINK_SLOTS` pairs (``first_seq``, ``last_seq``) of the recordings
             the writer process holds open, written by the loop's process only (the loop
             thread sets ``first_seq`` at a segment's first cycle, before its first frame
             is published): ``first_seq`` -1 = not begun, ``last_seq`` :data:`OPEN_END` =
             open-ended
=========  ===========================================================================

Torn reads: the reader copies frames ``[w1 - k, w1)`` after reading ``H_W = w1``, then reads
``H_W = w2`` again. While it copied, the kernel may have written up to frame
``w2 + ahead - 1``, which overwrote the rows of frames ``< w2 + ahead - n``; those frames of
the copy are discarded (:meth:`RingReader.recent`). The stream reads at most a few hundred
milliseconds behind a ring of many seconds, so in practice nothing is discarded; the check
makes it *correct* when the reader is starved (a busy machine) rather than *probably right*.
"""

from __future__ import annotations

import errno
import fcntl
import mmap
import os
import time
from multiprocessing import reduction

import numpy as np

MAGIC = 0x72696764_0002      # "rigd", layout 2 (layout 1 had no H_RD nor sink slots)
H_W, H_WALL, H_N, H_COLS, H_AHEAD, H_MAGIC, H_FS, H_RD = 0, 1, 2, 3, 4, 5, 6, 7
H_SINKS = 16                 # sink slots: (first_seq, last_seq) pairs from here
N_SINK_SLOTS = 8             # recordings open at once through the writer process, at most
OPEN_END = 1 << 62           # last_seq of an open-ended recording
HDR_SLOTS = H_SINKS + 2 * N_SINK_SLOTS   # 256 bytes: the ring starts 64-byte aligned


def _size(n: int, cols: int) -> int:
    return 8 * (HDR_SLOTS + n * cols)


class SharedRing:
    """Owner of the ring's shared memory (loop side).

    Parameters
    ----------
    n : int
        Ring capacity, frames.
    cols : int
        Columns per frame (``N_REC``).
    fs : float
        Loop rate, Hz (for readers; ``t`` of a frame is ``seq / fs``).

    Attributes
    ----------
    ring : numpy.ndarray
        float64 ``(n, cols)``, the kernel's ring (zeros at start).
    hdr : numpy.ndarray
        int64 header (see module docstring).
    """

    def __init__(self, n: int, cols: int, fs: float = 0.0) -> None:
        self.n, self.cols = int(n), int(cols)
        size = _size(self.n, self.cols)
        #: why the ring could not be shared (None when it is): the loop and the recorder work
        #: the same on a private ring, only the live stream is then unavailable
        self.unshared: str | None = None
        self.fd = -1
        try:
            self._mm = self._shared_map(size)
        except OSError as exc:
            # e.g. RLIMIT_FSIZE below the ring's size (memfd is a file: EFBIG), no memfd
            # (seccomp, old kernel): record and control anyway, refuse only the stream
            why = exc.strerror or str(exc)
            if exc.errno == errno.EFBIG:
                why += " (the process's file-size limit RLIMIT_FSIZE, systemd LimitFSIZE=)"
            self.unshared = f"cannot create the shared ring ({size / 2**20:.1f} MiB): {why}"
            if self.fd >= 0:
                os.close(self.fd)
                self.fd = -1
            self._mm = mmap.mmap(-1, size)           # anonymous, this process only
        self.hdr = np.ndarray((HDR_SLOTS,), dtype=np.int64, buffer=self._mm)
        self.ring = np.ndarray((self.n, self.cols), dtype=np.float64, buffer=self._mm,
                               offset=8 * HDR_SLOTS)
        self.hdr[H_N] = self.n
        self.hdr[H_COLS] = self.cols
        self.hdr[H_AHEAD] = 1
        self.hdr[H_FS] = int(round(fs * 1000))      # mHz, integer slot
        self.hdr[H_MAGIC] = MAGIC
        self._time_ns = time.time_ns

    def _shared_map(self, size: int) -> mmap.mmap:
        self.fd = os.memfd_create("rigd-ring", os.MFD_CLOEXEC | os.MFD_ALLOW_SEALING)
        os.ftruncate(self.fd, size)
        # the size is final: a reader can never truncate it under the loop (SIGBUS)
        seals = getattr(fcntl, "F_SEAL_SHRINK", 2) | getattr(fcntl, "F_SEAL_GROW", 4)
        try:
            fcntl.fcntl(self.fd, getattr(fcntl, "F_ADD_SEALS", 1033), seals)
        except OSError:
            pass
        return mmap.mmap(self.fd, size, flags=mmap.MAP_SHARED,
                         prot=mmap.PROT_READ | mmap.PROT_WRITE)

    def populate(self) -> None:
        """Fault every page of the ring in now, writable, contents unchanged (before the
        cycles start: never while the kernel writes).

        The ring is shared memory (4 KiB pages, no transparent huge pages for shmem by
        default): untouched, the kernel's first write to each page is a page fault, one
        every ~16 frames for the first pass through the ring (the ``loop_compute_us`` p99
        went from 0.7 to 3.2 µs with them). The real-time loop thread's ``mlockall``
        populates it; this does the same where that is not available.
        """
        try:
            self._mm.madvise(getattr(mmap, "MADV_POPULATE_WRITE", 23))   # Linux >= 5.14
        except (OSError, ValueError):
            flat = self.ring.reshape(-1)
            flat[::512] += 0.0                   # one write per 4 KiB page

    def set_ahead(self, frames: int) -> None:
        """The kernel may write up to ``frames`` beyond the published count (lock-step batch)."""
        self.hdr[H_AHEAD] = max(1, int(frames))

    def publish(self, w: int) -> None:
        """Frames up to total count ``w`` are written (loop thread).

        Runs in: loop thread — two stores into preallocated memory, no allocation beyond the
        integer ``time_ns`` returns, no lock, no system call besides the vDSO clock read. The
        wall time is stored first: a reader that reads ``H_WALL`` then ``H_W`` gets a time
        no later than the publication of the frames it reads (a latency figure is then an
        upper bound, never flattered).
        """
        hdr = self.hdr
        hdr[H_WALL] = self._time_ns()
        hdr[H_W] = w

    def handle(self) -> RingHandle | None:
        """A picklable handle for a spawned process (the file descriptor travels with it);
        None when the ring is not shared (:attr:`unshared` says why)."""
        if self.fd < 0:
            return None
        return RingHandle(self.fd, self.n, self.cols)


class RingHandle:
    """What the socket and writer processes receive to map the ring (pickled through ``spawn``).

    The file descriptor is duplicated into the child by :mod:`multiprocessing` while the
    process is started (:func:`multiprocessing.reduction.DupFd`), like the listening socket.
    """

    def __init__(self, fd: int, n: int, cols: int) -> None:
        self.fd, self.n, self.cols = fd, n, cols

    def __reduce__(self):
        return (_rebuild, (reduction.DupFd(self.fd), self.n, self.cols))


def _rebuild(dupfd, n: int, cols: int) -> RingHandle:
    return RingHandle(dupfd.detach(), n, cols)


class RingReader:
    """Read-only view of a :class:`SharedRing` in another process (the socket process).

    Parameters
    ----------
    handle : RingHandle
        As received through ``spawn`` (or :meth:`SharedRing.handle` in the same process,
        e.g. tests); the descriptor is reopened ``O_RDONLY`` and mapped ``PROT_READ``: this
        process cannot write the loop's memory.
    writable : bool
        Map it read-write (the writer process only: it stores its consumer index ``H_RD``
        and never writes the frames).
    """

    def __init__(self, handle: RingHandle, *, writable: bool = False) -> None:
        # the writer process alone maps it writable: it publishes its consumer index H_RD
        mode, prot = ((os.O_RDWR, mmap.PROT_READ | mmap.PROT_WRITE) if writable
                      else (os.O_RDONLY, mmap.PROT_READ))
        fd = os.open(f"/proc/self/fd/{handle.fd}", mode | os.O_CLOEXEC)
        try:
            self._mm = mmap.mmap(fd, _size(handle.n, handle.cols), flags=mmap.MAP_SHARED,
                                 prot=prot)
        finally:
            os.close(fd)
        self.hdr = np.ndarray((HDR_SLOTS,), dtype=np.int64, buffer=self._mm)
        if int(self.hdr[H_MAGIC]) != MAGIC:
            raise ValueError("not a rigd ring (bad magic)")
        self.n, self.cols = int(self.hdr[H_N]), int(self.hdr[H_COLS])
        self.ring = np.ndarray((self.n, self.cols), dtype=np.float64, buffer=self._mm,
                               offset=8 * HDR_SLOTS)
        self.fs = float(self.hdr[H_FS]) / 1000.0
        self.torn = 0          # frames discarded by the torn-read check (total)

    @property
    def published(self) -> int:
        """Frames published so far (total)."""
        return int(self.hdr[H_W])

    def recent(self, since: int, max_frames: int) -> tuple[int, np.ndarray, int]:
        """Copy the frames published after total count ``since`` (at most ``max_frames``).

        Parameters
        ----------
        since : int
            Total count already seen (frames ``< since`` are not wanted).
        max_frames : int
            At most this many frames, the newest ones.

        Returns
        -------
        first : int
            Total index of the first frame returned.
        frames : numpy.ndarray
            Copy, ``(k, cols)``, oldest first; possibly empty. Frames the writer may have
            overwritten while they were copied are not in it (counted in :attr:`torn`).
        wall_ns : int
            Wall time (``time.time_ns``) at or before the publication of the newest frame.
        """
        hdr = self.hdr
        wall = int(hdr[H_WALL])           # first: see SharedRing.publish
        w1 = int(hdr[H_W])
        ahead = int(hdr[H_AHEAD])
        lo = max(since, w1 - max_frames, w1 + ahead - self.n + 1, 0)
        if lo >= w1:
            return w1, np.empty((0, self.cols)), wall
        a, b = lo % self.n, (w1 - 1) % self.n + 1
        if a < b:
            out = self.ring[a:b].copy()
        else:                              # wraps around the end of the ring
            out = np.concatenate((self.ring[a:], self.ring[:b]))
        w2 = int(hdr[H_W])
        safe = w2 + ahead - self.n + 1     # frames below were possibly overwritten meanwhile
        if safe > lo:
            cut = min(safe - lo, len(out))
            self.torn += cut
            out = out[cut:]
            lo += cut
        return lo, out, wall
