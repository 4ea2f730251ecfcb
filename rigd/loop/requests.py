"""Fault requests from Python to the cycle kernel: one writer per slot, none cleared by the reader.

A thread that wants the safe state (the operator's ``trip``, a driver exception, an overrun
storm, a failed recording, a dead slow driver) *posts* a request. Each source ``s`` owns two
slots of the state array: ``st[S_FREQ + 3 s + 1]`` (the code) and ``st[S_FREQ + 3 s]`` (a request
counter it increments after writing the code). The kernel owns the third,
``st[S_FREQ + 3 s + 2]``: the counter value it has acknowledged
(:func:`rigd.loop.cycle.take_requests`). A request is pending while the two counters differ,
so a request posted at any moment — even while the kernel runs without the GIL in a lock-step
batch — is seen by the next cycle; there is no read-then-clear that could lose it.

Sources that several threads share (operator, slow drivers, recorder) serialise their writers
with a lock of their own; the kernel never takes it. The loop source is written only by the
thread running the cycles (real-time loop thread or lock-step caller) and takes no lock.
"""

from __future__ import annotations

import threading

import numpy as np

from rigd.loop.layout import N_REQ_SRC, S_FREQ

#: request sources (fixed slots; never renumber)
OPERATOR = 0      # trip() from any thread (service, signals, tests)
LOOP = 1          # the thread running the cycles: driver exceptions, overrun storm
RECORDER = 2      # the recorder: keeper thread, writer link thread (or the caller finishing)
SLOW = 3          # slow-driver threads and the monitor's staleness check

SOURCE_NAMES = ("operator", "loop", "recorder", "slow")
assert len(SOURCE_NAMES) == N_REQ_SRC


class FaultRequests:
    """The Python side of the request slots in ``st`` (see module docstring).

    Parameters
    ----------
    st : numpy.ndarray
        The loop's state array (:mod:`rigd.loop.layout`).
    """

    def __init__(self, st: np.ndarray) -> None:
        self._st = st
        self._locks = [threading.Lock() for _ in range(N_REQ_SRC)]

    def post(self, source: int, code: int) -> None:
        """Request the safe state with fault ``code`` from ``source`` (any thread).

        Runs in: any thread except the loop thread (takes the source's writer lock, which
        the kernel never takes).
        """
        b = S_FREQ + 3 * source
        with self._locks[source]:
            self._st[b + 1] = code
            self._st[b] += 1.0          # published after the code

    def post_from_loop(self, code: int) -> None:
        """Request from the thread running the cycles.

        Runs in: loop thread — O(1), allocation-free, non-blocking (the loop source has
        this one writer, so no lock).
        """
        st = self._st
        st[S_FREQ + 3 * LOOP + 1] = code
        st[S_FREQ + 3 * LOOP] += 1.0

    def posted(self, source: int) -> int:
        """Requests posted by ``source`` so far."""
        return int(self._st[S_FREQ + 3 * source])

    def acknowledged(self, source: int) -> int:
        """Requests of ``source`` the kernel has seen."""
        return int(self._st[S_FREQ + 3 * source + 2])

    def pending(self) -> bool:
        """True while a posted request has not been seen by a cycle yet."""
        return any(self.posted(s) != self.acknowledged(s) for s in range(N_REQ_SRC))
