"""The loop's watchdog: a process of its own that watches the cycle from outside.

A loop that stands still cannot say so: a stopped process (SIGSTOP, a debugger), a thread
stuck in a driver call or starved off its CPU runs no cycle, so nothing the cycle does — and
nothing else of the loop's process — can latch a fault or answer for it. This process can.
The daemon spawns it (by module name, like the socket process) with the loop's SAFE word
(:mod:`rigd.loop.safeword`: the kernel writes the time of every cycle into it, ``W_CYCLE_NS``)
and a pipe whose end tells it the daemon is gone. Every ``bound / 4`` (at most 5 ms) it
compares the age of the latest cycle with the stall bound (``W_STALL_BOUND_NS``,
:mod:`rigd.loop.liveness`):

* older than the bound: it writes a fresh value into the word's stall request
  (``W_STALL_REQ``) with the cycle the loop stands at and the stall's length so far — the
  *latch* of ``loop_stall``, which the kernel takes before anything else in the first cycle
  that runs again (as it takes a SAFE request), so the loop resumes in the safe state and the
  fault is in its history with its length; the socket process reads the same word and
  answers ``status`` (``stalled``, the age) and ``ping`` (not alive) from it meanwhile;
* while the loop stands it keeps the stall's length up to date (``W_STALL_NS``); when a cycle
  runs again it writes the whole length (the gap between the two cycles) and logs one line.

The outputs during the stall: the loop's process writes nothing, so the hardware keeps the last
drive — the serial front-end holds its own safe voltage once no drive frame came for its host
timeout (docs/service.md, "Serial front-end protocol"); this process cannot write the device
(the driver owns the port). It runs at SCHED_FIFO just below the loop thread when permitted
(else at the daemon's niceness, never niced further): a starved watchdog would miss stalls or
see false ones. Bound 0 (the daemon stopping, a lock-step loop): it only waits.
"""

from __future__ import annotations

import os
import signal
import sys
import time

from rigd.loop.safeword import (
    W_CYCLE_NS,
    W_SEQ,
    W_STALL_BOUND_NS,
    W_STALL_FROM,
    W_STALL_NS,
    W_STALL_REQ,
    W_WATCH_NS,
    fresh_value,
)

#: longest time between two looks, s
MAX_POLL_S = 0.005
#: looks per stall bound
LOOKS_PER_BOUND = 4


def main(word_handle, conn, priority: int | None = None) -> None:
    """Entry point of the spawned watchdog process (see module docstring).

    Parameters
    ----------
    word_handle : rigd.loop.safeword.WordHandle
        The loop's SAFE word (mapped read-write: the watchdog writes its stall slots only).
    conn : multiprocessing.connection.Connection
        Its end closes when the daemon ends (any way): the watchdog exits.
    priority : int, optional
        SCHED_FIFO priority (best effort).
    """
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_IGN)        # the daemon ends it (its pipe closes)
    if priority is not None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
        except (OSError, AttributeError, ValueError):
            pass
    w = word_handle.map(writable=True)
    watch(w, conn)


def watch(w, conn) -> None:
    """Watch the word ``w`` until ``conn`` reports its end (EOF) or a message."""
    stalled = False
    last_t = 0
    while True:
        bound = int(w[W_STALL_BOUND_NS])
        poll = MAX_POLL_S if bound <= 0 else min(MAX_POLL_S, bound / 1e9 / LOOKS_PER_BOUND)
        try:
            if conn.poll(poll):
                return                           # a message or EOF: the daemon is done
        except (OSError, EOFError):
            return
        now = time.monotonic_ns()
        w[W_WATCH_NS] = now
        t = int(w[W_CYCLE_NS])
        if t <= 0:
            stalled = False
            continue
        if stalled:
            if t != last_t:                      # it cycled again: the whole stall
                w[W_STALL_NS] = t - last_t
                stalled = False
                _say(f"loop ran again after standing still for {(t - last_t) / 1e9:.3f} s "
                     f"(cycle {int(w[W_STALL_FROM])})")
            else:
                w[W_STALL_NS] = now - t
            continue
        last_t = t
        if bound > 0 and now - t > bound:
            stalled = True
            w[W_STALL_FROM] = int(w[W_SEQ])
            w[W_STALL_NS] = now - t
            w[W_STALL_REQ] = fresh_value()       # the latch: taken by the next cycle
            _say(f"loop stands still: no cycle for {(now - t) / 1e6:.1f} ms after cycle "
                 f"{int(w[W_SEQ])} (stall bound {bound / 1e6:g} ms); loop_stall latched")


def _say(text: str) -> None:
    """One line to stderr (the daemon's log goes there too)."""
    try:
        sys.stderr.write(f"rigd watchdog: {text}\n")
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
