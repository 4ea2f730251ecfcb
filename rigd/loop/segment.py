"""Segments: an excitation played from a cycle boundary, with events and a recording range.

A :class:`Segment` is built and validated in the caller's thread (excitation array, sorted
events, sink); the :class:`SegmentPlayer` hands it to whichever thread runs the cycles, which
begins it at the next cycle boundary, fires its events, advances it and finishes it. The caller
waits on ``Segment.done``.

A segment played with ``stop_on_fault`` (experiments) ends at the cycle a fault is latched in
(or at its first cycle if one is latched already): the thread running the cycles only flags it
(:meth:`Segment.stop_for_fault`, O(1)) and frees the player's slot; the caller, waiting for it,
finishes it (:meth:`Segment.finish_faulted`) and closes its recording after that cycle.
"""

from __future__ import annotations

import collections
import threading
from dataclasses import dataclass

import numpy as np

from rigd.errors import InputError
from rigd.loop import faults as FC
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
    #: the latched fault that ended the segment early (``stop_on_fault``): seq, code, name,
    #: text; None when it played to its end
    fault: dict | None = None


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
    stop_on_fault : bool
        End at the cycle a fault is latched in (see module docstring).
    """

    def __init__(self, exc: np.ndarray, events, sink, controller_on,
                 stop_on_fault: bool = False) -> None:
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
        self.stop_on_fault = bool(stop_on_fault)
        #: code and cycle of the latched fault that ended it (0 / -1: none)
        self.fault_code = 0
        self.fault_seq = -1
        #: set by any thread (:meth:`SegmentPlayer.cancel`) to end it at the next cycle: its
        #: owner is gone and nobody must go on exciting the rig for it
        self.cancelled = False
        self.cancel_why = ""

    # --- the thread running the cycles ----------------------------------------------------
    def begin(self, st: np.ndarray, commands) -> None:
        """Start at the next cycle: note its sequence number, switch K∞ as asked.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.first_seq = int(st[L.S_SEQ])
        if self.sink is not None:         # the writer never writes past the planned end
            self.sink.first_seq = self.first_seq
            self.sink.last_seq = self.first_seq + self.n - 1
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

    def stop_for_fault(self, st: np.ndarray) -> None:
        """A fault is latched (``st[S_FAULT] != 0``) after cycle ``i - 1``: end the segment
        there. Only flags it; the waiting caller finishes it (:meth:`finish_faulted`).

        Runs in: loop thread — O(1), no array allocation, non-blocking (no event set).
        """
        self.last_seq = self.first_seq + self.i - 1
        if self.sink is not None:         # before the next frame is published
            self.sink.last_seq = self.last_seq
        self.fault_seq = int(st[L.S_FAULT_SEQ])
        self.fault_code = int(st[L.S_FAULT])

    def stop_cancelled(self, commands) -> None:
        """End after cycle ``i - 1`` because it was cancelled: the range and the recording end
        there, K∞ is restored as :meth:`finish` does and the caller is woken.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.last_seq = self.first_seq + self.i - 1
        if self.sink is not None:         # before the next frame is published
            self.sink.last_seq = self.last_seq
        if self.prev_target is not None:
            commands.enable(bool(self.prev_target))
        self.done.set()

    def finish_faulted(self, commands) -> None:
        """The caller's side of :meth:`stop_for_fault`: restore K∞ as :meth:`finish` does,
        mark the segment done (any thread, after the loop flagged it)."""
        if self.prev_target is not None:
            commands.enable(bool(self.prev_target))
        self.done.set()

    def fault_event(self, history: list[dict], st: np.ndarray) -> dict | None:
        """The fault (seq, code, name, text) that ended this segment, None if none did.

        ``history``: the loop's fault events (``ControlLoop.faults()``); any thread.
        """
        if not self.fault_code:
            return None
        for ev in reversed(history):
            if ev["code"] == self.fault_code and ev["seq"] == self.fault_seq:
                return {k: ev[k] for k in ("seq", "code", "name", "text")}
        return {"seq": self.fault_seq, "code": self.fault_code,
                "name": FC.fault_name(self.fault_code),
                "text": FC.describe(self.fault_code, int(st[L.S_FAULT_DETAIL]))}

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

    def stopped_for_fault(self, seg: Segment, st: np.ndarray) -> None:
        """A fault latched while ``seg`` played: free the slot, flag the segment (its caller
        finishes it).

        Runs in: loop thread — O(1), no array allocation, non-blocking.
        """
        self.current = None
        seg.stop_for_fault(st)

    def cancelled(self, seg: Segment, commands) -> None:
        """``seg`` was cancelled (:meth:`cancel`): free the slot, end it at this cycle.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.current = None
        seg.stop_cancelled(commands)

    def cancel(self, why: str) -> bool:
        """Ask the thread running the cycles to end the current segment at its next cycle
        (any thread; the excitation stops there and its recording is closed after it).
        False when no segment is playing."""
        seg = self.current
        if seg is None:
            return False
        seg.cancel_why = str(why)
        seg.cancelled = True
        return True

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
