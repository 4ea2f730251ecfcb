"""The command queue: operator commands from any thread, applied by the loop at a cycle boundary.

Producers (:class:`rigd.loop.loop.ControlLoop` methods, any thread) do every slow or
validating step first — a controller is checked and packed, an operating point's parameter
block is built — and post a small tuple. The thread running the cycles drains the queue
(:meth:`CommandQueue.apply`) between cycles (real time) or batches (lock-step); each command is
O(1) there. ``collections.deque.append``/``popleft`` are atomic, so producers never block the
loop and the loop never blocks producers.

A controller swap while K∞ is (being) blended in is done bumplessly: blend out, swap at
``ramp == 0``, blend back in (:attr:`CommandQueue.swap`).
"""

from __future__ import annotations

import collections

from rigd.loop import layout as L

ENABLE, CONTROLLER, RESET, CALL = range(4)


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
        #: a controller swap waiting for K∞ to blend out: (PackedController, re-enable after)
        self.swap = None

    # --- producers (any thread) ------------------------------------------------------
    def enable(self, on: bool) -> None:
        """Post: blend K∞ in (on) or out.

        Runs in: any thread, the loop thread too (segments) — O(1), non-blocking.
        """
        self.queue.append((ENABLE, bool(on)))

    def controller(self, packed) -> None:
        """Post: switch to an already validated and packed controller (bumplessly).

        Runs in: any thread — O(1), non-blocking (the validation and packing are done).
        """
        self.queue.append((CONTROLLER, packed))

    def reset(self) -> None:
        """Post: clear the latched fault. Runs in: any thread — O(1), non-blocking."""
        self.queue.append((RESET, None))

    def call(self, fn) -> None:
        """Post: run ``fn()`` at the next cycle boundary in the loop thread.

        ``fn`` must itself honour the loop-thread contract (O(1), allocation-free,
        non-blocking), e.g. a driver's prepared operating-point swap.
        """
        self.queue.append((CALL, fn))

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
            kind, arg = q.popleft()
            if kind == ENABLE:
                if self.swap is not None:
                    self.swap = (self.swap[0], arg)
                else:
                    st[L.S_K_TARGET] = 1.0 if arg else 0.0
            elif kind == CONTROLLER:
                if st[L.S_RAMP] == 0.0 and st[L.S_K_TARGET] == 0.0:
                    self._state.swap_controller(arg)
                else:  # blend out, swap, blend back in
                    self.swap = (arg, st[L.S_K_TARGET] != 0.0)
                    st[L.S_K_TARGET] = 0.0
            elif kind == RESET:
                self._state.reset_fault()
            else:
                arg()
        if self.swap is not None and st[L.S_RAMP] == 0.0:
            packed, back_on = self.swap
            self.swap = None
            self._state.swap_controller(packed)
            st[L.S_K_TARGET] = 1.0 if back_on else 0.0
