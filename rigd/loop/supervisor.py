"""The Python side of the supervisor: fault history, subscribers, the monitor thread, loop death.

The compiled cycle latches faults and appends them to a small log in ``st``
(:func:`rigd.loop.cycle.latch`). :class:`Supervisor` turns new log entries into fault events
(history for ``faults()``, one log line each, an event in every open recording, a message to
every subscriber queue), checks slow drivers for staleness in its monitor thread, and handles
the loop's death (:meth:`Supervisor.loop_died`): safe outputs at once, ``loop_died`` latched,
the loop stopped.
"""

from __future__ import annotations

import queue
import threading
import time

from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop import requests as RQ
from rigd.loop.cycle import latch
from rigd.loop.safeword import stall_text


class Supervisor:
    """Owner of fault reporting (see module docstring).

    Parameters
    ----------
    state : rigd.loop.state.KernelState
    requests : rigd.loop.requests.FaultRequests
    recorder : rigd.loop.recorder.Recorder
    log : structlog logger
    stale_s : float
        A slow driver without a good poll for this long latches ``slow_driver``.
    """

    def __init__(self, state, requests, recorder, log, stale_s: float) -> None:
        self._state = state
        self._requests = requests
        self._recorder = recorder
        self._log = log
        self._stale_s = stale_s
        self._history: list[dict] = []
        self._subscribers: list[queue.Queue] = []
        self._seen = 0
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.driver_error: BaseException | None = None
        #: what killed the loop (None while it lives)
        self.loop_error: BaseException | None = None
        self.slow = None            # rigd.loop.slow.SlowPollers, set by the loop
        self.fast = None            # the fast driver (its words for drv_status), set by the loop
        self.safe = None            # the SAFE word (a stall's length), set by the loop

    # --- requests from Python ------------------------------------------------------------
    def driver_failed(self, exc: BaseException) -> None:
        """A fast driver raised in read/write: keep the first error, request the safe state.

        Runs in: loop thread — O(1), non-blocking (the exception object exists already).
        """
        if self.driver_error is None:
            self.driver_error = exc
        self._requests.post_from_loop(FC.DRIVER_EXCEPTION)

    def recorder_failed(self, exc: BaseException) -> None:
        """A recording failed (writer thread): request the safe state, log it."""
        self._requests.post(RQ.RECORDER, FC.RECORDER_OVERFLOW)
        self._log.error("recording failed", error=str(exc))

    def loop_died(self, exc: BaseException, fast, stop: threading.Event) -> None:
        """The thread running the cycles raised: safe outputs now, latch, stop, log.

        Runs in: the dying loop thread (the kernel no longer runs, so this thread may write
        the fault into ``st`` directly). The fast driver's ``deactivate`` writes the safe
        drive; the front-end's own host-timeout hold stays the backstop if that fails too.
        """
        s = self._state
        try:
            fast.deactivate(s.safe_drive)
        except BaseException as wexc:  # noqa: BLE001 - report both, never raise from here
            self._log.error("could not write safe outputs after the loop died",
                            error=repr(wexc))
        if self.loop_error is None:
            self.loop_error = exc
        s.st[L.S_FAULT] = 0.0          # terminal: loop_died replaces any latched fault
        latch(s.st, FC.LOOP_DIED, -1)
        stop.set()
        self._log.error("loop died: outputs set safe, loop stopped", error=repr(exc))
        self.poll()

    def fault_text(self, code: int, detail: int) -> str:
        """:func:`rigd.loop.faults.describe`; for ``driver_status`` the status bits in words
        (the shared bits', the fast driver's ``status_names``, then its ``status_text`` for
        the rest, e.g. the simulated plant's contact); for ``slow_driver`` why it failed."""
        code, detail = int(code), int(detail)
        if code == FC.DRIVER_STATUS and detail > 0:
            own = dict(getattr(self.fast, "status_names", None) or {})
            named = 0
            for b in (*FC.STATUS_WORDS, *own):
                named |= b
            parts = [FC.status_words(detail & named, own)] if detail & named else []
            rest = detail & ~named
            if rest:
                words = self.fast.status_text(rest) if self.fast is not None else ""
                parts.append(words or FC.status_words(rest))
            return f"{FC.fault_text(code)}: {'; '.join(parts)}"
        text = FC.describe(code, detail)
        if code == FC.LOOP_STALL and self.safe is not None:
            text = stall_text(self.safe.word)
        if code == FC.SLOW_DRIVER and self.slow is not None:
            why = self.slow.reason()
            if why:
                text += f": {why}"
        return text

    # --- fault events ---------------------------------------------------------------------
    def subscribe(self) -> queue.Queue:
        """A queue receiving one dict per latched fault: seq, code, name, text, time."""
        q: queue.Queue = queue.Queue()
        self._subscribers.append(q)
        return q

    def history(self) -> list[dict]:
        """Every fault latched since start, oldest first."""
        self.poll()
        return list(self._history)

    def poll(self) -> None:
        """Turn new fault-log entries into events (monitor thread, runners, queries)."""
        with self._lock:
            st = self._state.st
            n = int(st[L.S_NFAULT])
            while self._seen < n:
                k = self._seen % L.FLOG_N
                seq, code, detail = st[L.S_FLOG + 3 * k:L.S_FLOG + 3 * k + 3]
                self._seen += 1
                ev = {"seq": int(seq), "code": int(code), "name": FC.fault_name(code),
                      "text": self.fault_text(code, int(detail)), "time": time.time()}
                if code == FC.DRIVER_EXCEPTION and self.driver_error is not None:
                    ev["text"] += f": {self.driver_error!r}"
                if code == FC.LOOP_DIED and self.loop_error is not None:
                    ev["text"] += f": {self.loop_error!r}"
                self._history.append(ev)
                self._recorder.add_event(ev["seq"], ev["code"],
                                         f"fault {ev['name']}: {ev['text']}")
                self._log.error("fault latched",
                                **{k2: v for k2, v in ev.items() if k2 != "time"})
                for q in self._subscribers:
                    q.put(ev)

    @property
    def unseen(self) -> bool:
        """New fault-log entries wait for :meth:`poll`.

        Runs in: loop thread (or any) — O(1), allocation-free, non-blocking.
        """
        return self._seen < self._state.st[L.S_NFAULT]

    # --- monitor thread ---------------------------------------------------------------------
    def start(self, stop: threading.Event) -> None:
        self._thread = threading.Thread(target=self._run, args=(stop,), name="rigd-monitor",
                                        daemon=True)
        self._thread.start()

    def join(self, timeout: float) -> None:
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self.poll()

    @property
    def native_id(self) -> int | None:
        return self._thread.native_id if self._thread is not None else None

    def _run(self, stop: threading.Event) -> None:
        while not stop.wait(0.02):
            self.poll()
            # also while another fault is latched: the outage is listed (once) beside it
            if self.slow is not None and self.slow.stale(self._stale_s):
                self._requests.post(RQ.SLOW, FC.SLOW_DRIVER)
        self.poll()
