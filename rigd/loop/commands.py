"""The command queue: operator commands from any thread, applied by the loop at a cycle boundary.

Producers (:class:`rigd.loop.loop.ControlLoop` methods, any thread) do every slow or
validating step first — a controller is checked and packed, an operating point's parameter
block is built — and post a small tuple. The thread running the cycles drains the queue
(:meth:`CommandQueue.apply`) between cycles (real time) or batches (lock-step); each command is
O(1) there. ``collections.deque.append``/``popleft`` are atomic, so producers never block the
loop and the loop never blocks producers.

A controller swap while K∞ is (being) blended in is done bumplessly: blend out, swap at
``ramp == 0``, blend back in (:attr:`CommandQueue.swap`).

Every post returns a :class:`Ticket` that the loop marks once it has applied the command (a
deferred controller swap once it is swapped in, or once a later load supersedes it). The mark
travels with the command, so a ticket is exact whatever order producers in several threads
append in. A caller that answers an operator (the daemon's ``load``, ``enable``, ``op``, ``reset``)
waits on it, so that the ``status`` read after the reply shows the change.
"""

from __future__ import annotations

import collections

from rigd.loop import layout as L

ENABLE, CONTROLLER, RESET, CALL = range(4)


class Ticket:
    """One posted command: :attr:`applied` is set True by the loop thread once it acted on it
    (attribute assignment: no allocation, no lock)."""

    __slots__ = ("applied",)

    def __init__(self) -> None:
        self.applied = False


class CommandQueue:
    """Owner of the pending commands and of a pending bumpless controller swap.

    Parameters
    ----------
    state : rigd.loop.state.KernelState
        The arrays the commands act on.
    """

    def __init__(self, state) -> None:
        #: the queued commands (read by the loop thread to skip :meth:`apply` when empty)
        self.queue: collections.deque = collections.deque()
        self._state = state
        #: a controller swap waiting for K∞ to blend out: (PackedController, re-enable after,
        #: Ticket)
        self.swap = None

    # --- producers (any thread) ------------------------------------------------------
    def _post(self, kind: int, arg) -> Ticket:
        t = Ticket()
        self.queue.append((kind, arg, t))
        return t

    def enable(self, on: bool) -> Ticket:
        """Post: blend K∞ in (on) or out; returns the ticket.

        Runs in: any thread, the loop thread too (segments) — O(1), non-blocking.
        """
        return self._post(ENABLE, bool(on))

    def controller(self, packed) -> Ticket:
        """Post: switch to an already validated and packed controller (bumplessly); returns
        the ticket.

        Runs in: any thread — O(1), non-blocking (the validation and packing are done).
        """
        return self._post(CONTROLLER, packed)

    def reset(self) -> Ticket:
        """Post: clear the latched fault; returns the ticket.

        Runs in: any thread — O(1), non-blocking.
        """
        return self._post(RESET, None)

    def call(self, fn) -> Ticket:
        """Post: run ``fn()`` at the next cycle boundary in the loop thread; returns the ticket.

        ``fn`` must itself honour the loop-thread contract (O(1), allocation-free,
        non-blocking), e.g. a driver's prepared operating-point swap.
        """
        return self._post(CALL, fn)

    @staticmethod
    def applied(ticket: Ticket) -> bool:
        """Has the loop applied the command with this ticket? Runs in: any thread — O(1)."""
        return ticket.applied

    def __bool__(self) -> bool:
        return bool(self.queue) or self.swap is not None

    # --- consumer ---------------------------------------------------------------------
    def apply(self) -> None:
        """Apply every queued command, then a pending swap once K∞ has blended out.

        Runs in: loop thread (the thread running the cycles, at a cycle or batch boundary) —
        O(1) per command, allocation-free, non-blocking.
        """
        st = self._state.st
        q = self.queue
        while q:
            kind, arg, ticket = q.popleft()
            if kind == ENABLE:
                sw = self.swap
                if sw is not None:
                    self.swap = (sw[0], arg, sw[2])
                else:
                    st[L.S_K_TARGET] = 1.0 if arg else 0.0
            elif kind == CONTROLLER:
                sw = self.swap
                if sw is not None:      # a newer load replaces the waiting one (same re-enable)
                    self.swap = (arg, sw[1], ticket)
                    sw[2].applied = True          # superseded: done with it
                    continue
                if st[L.S_RAMP] != 0.0 or st[L.S_K_TARGET] != 0.0:
                    self.swap = (arg, st[L.S_K_TARGET] != 0.0, ticket)   # blend out first
                    st[L.S_K_TARGET] = 0.0
                    continue
                self._state.swap_controller(arg)
            elif kind == RESET:
                self._state.reset_fault()
            else:
                arg()
            ticket.applied = True
        if self.swap is not None and st[L.S_RAMP] == 0.0:
            packed, back_on, ticket = self.swap
            self._state.swap_controller(packed)
            st[L.S_K_TARGET] = 1.0 if back_on else 0.0
            self.swap = None
            ticket.applied = True
