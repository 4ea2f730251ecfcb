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

**Applied when answered, or never.** A ticket carries the SAFE generation its command was
sent in (``st[S_SAFE_GEN]``, :mod:`rigd.loop.safeword`) and optionally a deadline. The loop
*drops* a command instead of applying it when a SAFE was taken since it was sent (SAFE clears
the queue), when its deadline has passed, when it is ``enable`` while a fault is latched, or
when its caller cancelled it (:meth:`Ticket.cancel`: the caller stopped waiting and answered
"failed"). Loop and caller *claim* a ticket (an atomic ``dict.pop``): exactly one of them decides
its fate, so a command the caller reported as dropped is never applied afterwards.
"""

from __future__ import annotations

import collections
import time

from rigd.errors import InputError
from rigd.loop import layout as L

ENABLE, CONTROLLER, RESET, CALL = range(4)

#: why a command was dropped (:attr:`Ticket.dropped`)
DROP_SAFE = "overtaken by SAFE (sent before the safe state was requested)"
DROP_LATE = "not applied before its deadline (the caller was told it failed)"
DROP_FAULT = "refused: a fault is latched (reset it first)"


class CommandDropped(InputError):
    """A command dropped instead of applied (one line naming it and why)."""


class Ticket:
    """One posted command (see the module docstring).

    Attributes
    ----------
    applied : bool
        Set True by the loop thread once it acted on it.
    dropped : str
        Why it was dropped, never to be applied ("" while not dropped).
    gen : float
        SAFE generation it was sent in.
    deadline_ns : int
        ``time.monotonic_ns()`` after which it is dropped (0: none).
    """

    __slots__ = ("applied", "dropped", "gen", "deadline_ns", "_claim")

    def __init__(self, gen: float = 0.0, deadline_ns: int = 0) -> None:
        self.applied = False
        self.dropped = ""
        self.gen = gen
        self.deadline_ns = deadline_ns
        self._claim = {0: True}

    def claim(self) -> bool:
        """Take the decision on this command (True once, for the first caller, any thread):
        one ``dict.pop`` under the interpreter lock, no allocation."""
        return self._claim.pop(0, None) is not None

    def cancel(self, why: str = DROP_LATE) -> bool:
        """The caller gives up (any thread): True if the loop will now never apply it; False if
        the loop claimed it first (then :attr:`applied` or :attr:`dropped` is set at once)."""
        if not self.claim():
            return False
        self.dropped = why
        return True

    @property
    def done(self) -> bool:
        return self.applied or bool(self.dropped)


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
    def _post(self, kind: int, arg, gen: float | None = None, deadline: float | None = None
              ) -> Ticket:
        if gen is None:
            gen = float(self._state.st[L.S_SAFE_GEN])
        t = Ticket(float(gen), 0 if deadline is None else int(deadline * 1e9))
        self.queue.append((kind, arg, t))
        return t

    def enable(self, on: bool, gen: float | None = None, deadline: float | None = None
               ) -> Ticket:
        """Post: blend K∞ in (on) or out; returns the ticket.

        ``gen``: the SAFE generation the command was sent in (default: now); ``deadline``:
        ``time.monotonic()`` after which it is dropped (default: none). Same for every post.

        Runs in: any thread, the loop thread too (segments) — O(1), non-blocking.
        """
        return self._post(ENABLE, bool(on), gen, deadline)

    def controller(self, packed, gen: float | None = None, deadline: float | None = None
                   ) -> Ticket:
        """Post: switch to an already validated and packed controller (bumplessly); returns
        the ticket.

        Runs in: any thread — O(1), non-blocking (the validation and packing are done).
        """
        return self._post(CONTROLLER, packed, gen, deadline)

    def reset(self, gen: float | None = None, deadline: float | None = None) -> Ticket:
        """Post: clear the latched fault; returns the ticket.

        Runs in: any thread — O(1), non-blocking.
        """
        return self._post(RESET, None, gen, deadline)

    def call(self, fn, gen: float | None = None, deadline: float | None = None) -> Ticket:
        """Post: run ``fn()`` at the next cycle boundary in the loop thread; returns the ticket.

        ``fn`` must itself honour the loop-thread contract (O(1), allocation-free,
        non-blocking), e.g. a driver's prepared operating-point swap.
        """
        return self._post(CALL, fn, gen, deadline)

    @staticmethod
    def applied(ticket: Ticket) -> bool:
        """Has the loop applied the command with this ticket? Runs in: any thread — O(1)."""
        return ticket.applied

    def __bool__(self) -> bool:
        return bool(self.queue) or self.swap is not None

    # --- consumer ---------------------------------------------------------------------
    @staticmethod
    def _stale(ticket: Ticket, st, now_ns: int) -> str:
        """Why ``ticket`` must not be applied now ("" if it may). Loop thread, O(1)."""
        if ticket.gen != st[L.S_SAFE_GEN]:
            return DROP_SAFE
        if ticket.deadline_ns and now_ns > ticket.deadline_ns:
            return DROP_LATE
        return ""

    def apply(self) -> None:
        """Apply every queued command (or drop it, see the module docstring), then a pending
        swap once K∞ has blended out.

        Runs in: loop thread (the thread running the cycles, at a cycle or batch boundary) —
        O(1) per command, allocation-free (but the clock read), non-blocking.
        """
        st = self._state.st
        q = self.queue
        now = time.monotonic_ns() if (q or self.swap is not None) else 0
        while q:
            kind, arg, ticket = q.popleft()
            if kind == CONTROLLER and not self._stale(ticket, st, now) and (
                    self.swap is not None or st[L.S_RAMP] != 0.0 or st[L.S_K_TARGET] != 0.0):
                # deferred until K∞ has blended out: claimed when swapped in
                sw = self.swap
                if sw is not None:      # a newer load replaces the waiting one (same re-enable)
                    self.swap = (arg, sw[1], ticket)
                    if sw[2].claim():
                        sw[2].applied = True      # superseded: done with it
                else:
                    self.swap = (arg, st[L.S_K_TARGET] != 0.0, ticket)   # blend out first
                    st[L.S_K_TARGET] = 0.0
                continue
            if not ticket.claim():
                continue                          # its caller gave up: never applied
            why = self._stale(ticket, st, now)
            if not why and kind == ENABLE and arg and st[L.S_FAULT] != 0.0:
                why = DROP_FAULT
            if why:
                ticket.dropped = why
                continue
            if kind == ENABLE:
                sw = self.swap
                if sw is not None:
                    self.swap = (sw[0], arg, sw[2])
                else:
                    st[L.S_K_TARGET] = 1.0 if arg else 0.0
            elif kind == CONTROLLER:
                self._state.swap_controller(arg)
            elif kind == RESET:
                self._state.reset_fault()
            else:
                arg()
            ticket.applied = True
        sw = self.swap
        if sw is not None:
            packed, back_on, ticket = sw
            why = self._stale(ticket, st, now)
            if why or st[L.S_RAMP] == 0.0:
                self.swap = None
                if not ticket.claim():            # its caller gave up: K∞ as it was asked
                    st[L.S_K_TARGET] = 1.0 if back_on and st[L.S_FAULT] == 0.0 else 0.0
                elif why:
                    ticket.dropped = why
                    if why is DROP_LATE:
                        st[L.S_K_TARGET] = 1.0 if back_on and st[L.S_FAULT] == 0.0 else 0.0
                else:
                    self._state.swap_controller(packed)
                    st[L.S_K_TARGET] = 1.0 if back_on else 0.0
                    ticket.applied = True
