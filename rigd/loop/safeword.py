"""The SAFE request word: a page of shared memory the cycle reads every cycle.

SAFE must reach the loop whatever else is going on: all client slots taken, the command worker
blocked, the socket process busy or restarting. So it needs none of them. The daemon maps a
small file beside its control socket (``<socket>.safe``, the socket's permissions, 0660 by
default); anyone allowed to use the socket may map it too and *write a request into it*; the
compiled cycle compares the request slot with the value it last took, every cycle (two loads,
one compare: O(1), no allocation, no lock, no system call), and on a change latches
``operator_safe`` in that same cycle and writes its acknowledgement.

Layout (int64 slots, :data:`N_SLOTS` of them, at the start of one 4 KiB page):

==================  ===========================================================================
``W_MAGIC``          :data:`MAGIC` (layout version; written once by the owner)
``W_PID``            the daemon's process id (for messages)
``W_REQ``            **requesters write a fresh random value here** (52 bits, never 0)
``W_SEQ``            kernel: the number of the cycle running now (written every cycle)
``W_ACK_N``          kernel: requests taken so far
``W_ACK_SEQ``        kernel: the cycle at which it took the last request (the safe state holds
                     from that cycle on)
``W_ACK_CODE``       kernel: the fault latched then (``operator_safe``, or an earlier fault: the
                     first one wins; the safe state is the same)
``W_ACK_FAULT_SEQ``  kernel: the cycle at which that fault latched
``W_CYCLE_NS``       the loop: ``CLOCK_MONOTONIC`` time of its latest cycle, ns (real time: the
                     cycle's wake-up, written by the kernel; lock-step: after each batch)
``W_FAULT``          kernel: the fault latched now (0: none), written every cycle
``W_FAULT_SEQ``      kernel: the cycle at which it latched
``W_STALL_REQ``      **the watchdog process writes a fresh value here** when the loop stalled
                     longer than its bound (:mod:`rigd.service.watchdog`): the kernel latches
                     ``loop_stall`` in the first cycle that runs
``W_STALL_FROM``     watchdog: the cycle number the loop stood at when the stall was seen
``W_STALL_NS``       watchdog: how long the loop has stood (while it stands; the whole stall
                     once it cycles again), ns
``W_LOOP_GAP_NS``    kernel: the latest gap between two cycles beyond the stall bound (the
                     stall's length as the loop measured it when it ran again), ns
``W_STALL_BOUND_NS`` the owner: the stall bound, ns (:mod:`rigd.loop.liveness`; 0: no watch)
``W_WATCH_NS``       watchdog: ``CLOCK_MONOTONIC`` time of its latest look, ns (is it alive?)
==================  ===========================================================================

The value the kernel last took lives in the loop's private state array (``st[S_SAFE_SEEN]``),
not in this page: nothing written into the page can hide a request from the kernel. A request
is confirmed to its requester by ``W_ACK_SEQ >= c0``, where ``c0`` is ``W_SEQ`` read *before*
writing the request: whichever request the kernel took at a cycle from ``c0`` on (two
requesters may overwrite each other's value), the safe state latched after the request was
made. ``st[S_SAFE_GEN]`` (requests taken) lets the command queue drop commands that a SAFE
overtook (:mod:`rigd.loop.commands`).

This module is the loop's side (owner of the memory) and the layout shared with the requesters
(:mod:`rigd.service.safe_request`); it imports nothing heavy so that ``rigd ctl safe`` starts
fast.
"""

from __future__ import annotations

import mmap
import os
import tempfile
import time
import weakref

import numpy as np

MAGIC = 0x72696764_5346_01      # "rigd" "SF", layout 1 (slots 8.. appended: liveness)
W_MAGIC, W_PID, W_REQ, W_SEQ, W_ACK_N, W_ACK_SEQ, W_ACK_CODE, W_ACK_FAULT_SEQ = range(8)
(W_CYCLE_NS, W_FAULT, W_FAULT_SEQ, W_STALL_REQ, W_STALL_FROM, W_STALL_NS, W_LOOP_GAP_NS,
 W_STALL_BOUND_NS) = range(8, 16)
W_WATCH_NS = 16
N_SLOTS = 32
#: bytes of the shared file (one page)
SIZE = 4096


def _view(mm: mmap.mmap) -> np.ndarray:
    return np.ndarray((N_SLOTS,), dtype=np.int64, buffer=mm)


class SafeWord:
    """The loop's SAFE request word (see module docstring).

    Starts on private anonymous memory (a loop without a daemon: tests, benches, experiments
    run in-process); :meth:`attach_file` moves it to a file other processes can map, before the
    cycles start.

    Attributes
    ----------
    word : numpy.ndarray
        int64 ``(N_SLOTS,)``, the array the kernel reads and acknowledges in.
    path : str or None
        The shared file, once attached.
    """

    def __init__(self) -> None:
        #: descriptor of the memory (a memfd until :meth:`attach_file`): handed to the
        #: watchdog and socket processes (:meth:`handle`)
        self.fd = os.memfd_create("rigd-safe", os.MFD_CLOEXEC)
        self._fds = [self.fd]                       # closed when the word is collected
        weakref.finalize(self, _close_all, self._fds)
        os.ftruncate(self.fd, SIZE)
        self._mm = mmap.mmap(self.fd, SIZE, flags=mmap.MAP_SHARED,
                             prot=mmap.PROT_READ | mmap.PROT_WRITE)
        self.word = _view(self._mm)
        self._init()
        self.path: str | None = None
        self._ino: tuple[int, int] | None = None

    def handle(self) -> WordHandle:
        """What another process needs to map this word (pickled through ``spawn``)."""
        return WordHandle(self.fd)

    def _init(self) -> None:
        self.word[:] = 0
        self.word[W_MAGIC] = MAGIC
        self.word[W_PID] = os.getpid()

    def attach_file(self, path: str, mode: int = 0o660) -> str:
        """Create ``path`` (replacing a stale one atomically), map it and use it from now on.

        Called by the daemon after it bound the control socket (a live daemon's files are
        never touched: its socket refused the bind) and before the cycles start (the loop
        thread takes :attr:`word` when it starts). The file gets ``mode`` (the socket's).

        Raises
        ------
        OSError
            The folder is not writable (the caller logs it; ``safe`` then goes by the socket).
        """
        d = os.path.dirname(os.path.abspath(path))
        fd, tmp = tempfile.mkstemp(prefix=".rigd-safe-", dir=d)
        try:
            os.fchmod(fd, mode)
            os.ftruncate(fd, SIZE)
            mm = mmap.mmap(fd, SIZE, flags=mmap.MAP_SHARED,
                           prot=mmap.PROT_READ | mmap.PROT_WRITE)
            st = os.fstat(fd)
            os.replace(tmp, path)
        except BaseException:
            os.close(fd)
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
            raise
        old = self.word.copy()
        self.fd = fd
        self._fds.append(fd)
        self._mm = mm
        self.word = _view(mm)
        self.word[:] = old
        self.word[W_REQ] = 0
        self.path, self._ino = path, (st.st_dev, st.st_ino)
        return path

    def detach_file(self) -> None:
        """Remove the shared file if it is still ours (the mapping stays valid for the loop)."""
        if self.path is None:
            return
        try:
            st = os.stat(self.path)
            if (st.st_dev, st.st_ino) == self._ino:
                os.unlink(self.path)
        except FileNotFoundError:
            pass
        self.path = None

    def request(self) -> int:
        """Post a SAFE request from this process (any thread); returns ``c0`` (see the module
        docstring: confirmed once ``acknowledged_at() >= c0``)."""
        c0 = int(self.word[W_SEQ])
        self.word[W_REQ] = fresh_value()
        return c0

    def acknowledged_at(self) -> int:
        """The cycle at which the kernel took the last request (-1: none yet)."""
        return int(self.word[W_ACK_SEQ]) if int(self.word[W_ACK_N]) else -1


class WordHandle:
    """A SAFE word's descriptor for another process (duplicated into it by
    :mod:`multiprocessing` when it is spawned, like the ring's :class:`RingHandle`)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def __reduce__(self):
        from multiprocessing import reduction

        return (_rebuild, (reduction.DupFd(self.fd),))

    def map(self, writable: bool = False) -> np.ndarray:
        """The word as an int64 array in this process (read-only unless ``writable``)."""
        prot = mmap.PROT_READ | (mmap.PROT_WRITE if writable else 0)
        mm = mmap.mmap(self.fd, SIZE, flags=mmap.MAP_SHARED, prot=prot)
        view = np.ndarray((N_SLOTS,), dtype=np.int64, buffer=mm)
        if not writable:
            view.flags.writeable = False
        return view


def _rebuild(dupfd) -> WordHandle:
    return WordHandle(dupfd.detach())


def stall_text(w) -> str:
    """The ``loop_stall`` fault's words from a SAFE word ``w`` (any process): how long the loop
    stood, after which cycle, against which bound."""
    gap = max(int(w[W_LOOP_GAP_NS]), int(w[W_STALL_NS]))
    bound = int(w[W_STALL_BOUND_NS])
    text = "the loop stood still"
    if gap > 0:
        text += f" for {gap / 1e9:.3f} s"
    if int(w[W_STALL_FROM]) > 0:
        text += f" after cycle {int(w[W_STALL_FROM])}"
    if bound > 0:
        text += f" (stall bound {bound / 1e6:g} ms)"
    return text + "; outputs held, then safe"


def age_s(w, now_ns: int | None = None) -> float | None:
    """Seconds since the loop's latest cycle (``W_CYCLE_NS``), None before its first."""
    t = int(w[W_CYCLE_NS])
    if t <= 0:
        return None
    return max(0, (time.monotonic_ns() if now_ns is None else now_ns) - t) / 1e9


def live(w, now_ns: int | None = None) -> dict:
    """What the word says of the loop now (any process; the socket process's ``status`` and
    ``ping`` overlay it on the daemon's snapshot, which can be older).

    Returns
    -------
    dict
        ``seq`` (the cycle running now), ``age_s`` (s since its latest cycle; None before the
        first), ``stall_bound_s`` (None: not watched), ``stalled`` (older than the bound, or
        the watchdog's stall still open), ``fault`` (code, seq of the fault in force, as the
        kernel wrote it last), ``stall`` (the latest stall: ``cycle``, ``length_s``, ``text``;
        None before one).
    """
    now = time.monotonic_ns() if now_ns is None else now_ns
    age = age_s(w, now)
    bound = int(w[W_STALL_BOUND_NS])
    stalled = bound > 0 and age is not None and age * 1e9 > bound
    gap = max(int(w[W_LOOP_GAP_NS]), int(w[W_STALL_NS]))
    return {"seq": int(w[W_SEQ]), "age_s": None if age is None else round(age, 6),
            "stall_bound_s": bound / 1e9 if bound > 0 else None, "stalled": stalled,
            "fault": {"code": int(w[W_FAULT]), "seq": int(w[W_FAULT_SEQ])},
            "stall": ({"cycle": int(w[W_STALL_FROM]), "length_s": round(gap / 1e9, 6),
                       "text": stall_text(w)} if gap > 0 or stalled else None)}


def _close_all(fds: list[int]) -> None:
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass


def fresh_value() -> int:
    """A random non-zero request value of 52 bits (exact as the kernel's float64 copy)."""
    return (int.from_bytes(os.urandom(7), "little") & ((1 << 52) - 1)) | 1


def word_path(socket_path: str) -> str:
    """The SAFE word file that belongs to a control socket."""
    return str(socket_path) + ".safe"
