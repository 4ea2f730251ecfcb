"""Segments: an excitation played from a cycle boundary, with events and a recording range.

A :class:`Segment` is built and validated in the caller's thread (excitation array, sorted
events, sink); the :class:`SegmentPlayer` hands it to whichever thread runs the cycles, which
begins it at the next cycle boundary, fires its events, advances it and finishes it. The caller
waits on ``Segment.done``.
"""

from __future__ import annotations

import collections
import threading
from dataclasses import dataclass

import numpy as np

from rigd.errors import InputError
from rigd.loop import layout as L

#: the excitation of "no segment" (exc_i = -1)
NO_EXCITATION = np.zeros((1, 2))


@dataclass
class SegmentResult:
    """What ``run_segment`` played: frames ``first_seq..last_seq`` (inclusive).

    ``frames`` holds the recorded frames for ``record="memory"``; ``faults`` the faults that
    latched during the segment.
    """

    first_seq: int
    last_seq: int
    n_frames: int
    path: str | None = None
    frames: np.ndarray | None = None
    faults: list | None = None


class Segment:
    """One excitation being played (see module docstring).

    Parameters
    ----------
    exc : float64 (n, 2)
        Excitation per cycle, V (already padded with the pre/post cycles).
    events : sequence of (cycle index, callable)
    sink : rigd.loop.sinks.Sink or None
    controller_on : bool or None
        Enable/disable K∞ at the first cycle, restored after the last.
    """

    def __init__(self, exc: np.ndarray, events, sink, controller_on) -> None:
        self.exc = exc
        self.n = len(exc)
        self.i = 0
        self.events = collections.deque(sorted(events, key=lambda e: e[0]))
        self.sink = sink
        self.controller_on = controller_on
        self.prev_target: float | None = None
        self.first_seq = -1
        self.last_seq = -1
        self.done = threading.Event()
        self.error: BaseException | None = None

    # --- the thread running the cycles ----------------------------------------------------
    def begin(self, st: np.ndarray, commands) -> None:
        """Start at the next cycle: note its sequence number, switch K∞ as asked.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.first_seq = int(st[L.S_SEQ])
        if self.sink is not None:
            self.sink.first_seq = self.first_seq
        if self.controller_on is not None:
            self.prev_target = float(st[L.S_K_TARGET])
            commands.enable(self.controller_on)
            commands.apply()

    def fire_events(self) -> None:
        """Run the events due before cycle ``i`` (an exception is kept for the caller).

        Runs in: loop thread — the events are the caller's callables and must themselves
        be O(1) and non-blocking (e.g. ``plant.impact``).
        """
        ev = self.events
        while ev and ev[0][0] <= self.i:
            _, fn = ev.popleft()
            try:
                fn()
            except Exception as exc:  # noqa: BLE001 - reported to the caller
                self.error = exc

    def finish(self, commands) -> None:
        """The last cycle has run: restore K∞, wake the caller.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.last_seq = self.first_seq + self.n - 1
        if self.prev_target is not None:
            commands.enable(bool(self.prev_target))
        self.done.set()

    def abort(self, why: str) -> None:
        """The loop stopped before the last cycle (any thread, after the cycles stopped)."""
        self.error = RuntimeError(why)
        self.done.set()


class SegmentPlayer:
    """The one slot through which a caller hands a segment to the thread running the cycles."""

    def __init__(self) -> None:
        self.current: Segment | None = None
        self._offer = threading.Lock()

    def offer(self, seg: Segment) -> bool:
        """Hand ``seg`` to the loop thread; False if another segment is playing (any thread)."""
        with self._offer:
            if self.current is not None:
                return False
            self.current = seg
            return True

    def finished(self, seg: Segment, commands) -> None:
        """``seg`` played its last cycle: free the slot and finish it.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.current = None
        seg.finish(commands)

    def abort(self, why: str) -> None:
        """Abort the current segment, if any (after the cycles stopped)."""
        seg, self.current = self.current, None
        if seg is not None:
            seg.abort(why)


def segment_inputs(excitation, events, pre: int, post: int):
    """Validate a segment's inputs in the caller's thread; the padded excitation and events.

    Returns ``(full, events)``: float64 (pre + n + post, 2) and ``[(cycle index, callable)]``.
    """
    exc = np.asarray(excitation, dtype=float)
    if exc.ndim != 2 or exc.shape[1] != 2:
        raise InputError(f"excitation must be an (n, 2) array of [r_x, r_y] volts, got shape "
                         f"{exc.shape}")
    if not np.all(np.isfinite(exc)):
        raise InputError("excitation contains NaN or Inf")
    if pre < 0 or post < 0:
        raise InputError("pre and post must be >= 0 cycles")
    full = np.zeros((pre + len(exc) + post, 2))
    full[pre:pre + len(exc)] = exc
    evs = []
    for off, fn in events:
        idx = pre + int(off)
        if not 0 <= idx < len(full):
            raise InputError(f"event at cycle offset {off} is outside the segment "
                             f"[-{pre}, {len(exc) + post})")
        if not callable(fn):
            raise InputError(f"event at cycle offset {off} is not callable ({fn!r})")
        evs.append((idx, fn))
    return full, evs
