"""Slow-driver pollers: one thread per slow driver, latest values posted into the kernel state.

Each thread polls its driver at ``poll_hz`` and writes Ω and P_I into ``st[S_SLOW_OMEGA]`` /
``st[S_SLOW_PINJ]`` (one writer per slot: the thread of the driver that provides it); a
failing poll requests ``slow_driver`` once per outage. Setpoints are sent from short-lived
threads so no caller waits on a device.

Validity: while a driver's poll fails, or it had no good poll for the staleness bound, the
channels it provides (those of its last good poll; Ω and P_I before the first) are marked
invalid in ``st[S_SLOW_BAD]`` — the recording gets NaN for them, never the held value
(docs/data.md); the held value stays in ``st[S_SLOW_*]`` for the loop. A good poll clears
them. Why it failed is kept for the fault list (:meth:`SlowPollers.reason`).

Staleness (:meth:`SlowPollers.stale`, checked by the supervisor's monitor thread): a driver's
clock starts at its first good poll. Until then the bound is ``first_poll_s``
(``supervisor.slow_first_poll_s``, counted from :meth:`SlowPollers.start`): the first poll of a
fresh device includes its connect and may take a few device timeouts, and a clock started
before it latched ``slow_driver`` at cycle 0 on a slow connect. A device that refuses or does
not answer is not waited for: its failing poll requests the fault at once.
"""

from __future__ import annotations

import threading
import time

from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop import requests as RQ

#: bit of each slow channel in ``st[S_SLOW_BAD]``
CHANNEL_BITS = {"omega_rpm": 1, "p_inj_bar": 2}


class SlowPollers:
    """Owner of the slow drivers' threads (see module docstring)."""

    def __init__(self, drivers, poll_hz, st, requests, log, first_poll_s: float = 10.0) -> None:
        self.drivers = list(drivers)
        self._hz = list(poll_hz) or [getattr(d, "poll_hz", 20.0) for d in self.drivers]
        self._st = st
        self._requests = requests
        self._log = log
        self._first_poll_s = float(first_poll_s)
        # per driver: start of its staleness clock (monotonic s; set by the driver's thread at
        # each good poll, restarted by the monitor on a report) and whether it has had a good
        # poll (before that the bound is first_poll_s)
        self._since: list[float] = []
        self._polled: list[bool] = []
        self._threads: list[threading.Thread] = []
        self._bits: list[int] = []         # per driver: the channels of its last good poll
        self._why: list[str] = []          # per driver: why it is invalid ("" while valid)
        self._bad_lock = threading.Lock()  # S_SLOW_BAD: one read-modify-write at a time

    def start(self, stop: threading.Event) -> None:
        now = time.monotonic()
        for i, d in enumerate(self.drivers):
            self._since.append(now)
            self._polled.append(False)
            self._bits.append(CHANNEL_BITS["omega_rpm"] | CHANNEL_BITS["p_inj_bar"])
            self._why.append("")
            t = threading.Thread(target=self._run, args=(i, d, stop), name=f"rigd-slow-{i}",
                                 daemon=True)
            t.start()
            self._threads.append(t)

    @property
    def native_ids(self) -> list[int]:
        return [t.native_id for t in self._threads]

    def stale(self, stale_s: float) -> bool:
        """True if a driver had no good poll for ``stale_s`` s, or no first good poll within
        ``first_poll_s`` s of :meth:`start` (its clock restarts: one report per period)."""
        now = time.monotonic()
        hit = False
        for i, t in enumerate(self._since):
            bound = stale_s if self._polled[i] else self._first_poll_s
            if now - t > bound:
                self._since[i] = now
                hit = True
                self._invalid(i, f"{self.drivers[i].name}: no good poll for {now - t:.1f} s "
                                 f"(bound {bound:g} s)")
        return hit

    def reason(self) -> str:
        """Why the slow channels are invalid, one line per failing driver (``"; "``-joined),
        or the last reason when none fails any more."""
        with self._bad_lock:
            return "; ".join(w for w in self._why if w) or getattr(self, "_last_why", "")

    def _invalid(self, i: int, why: str) -> None:
        with self._bad_lock:
            self._why[i] = why
            self._last_why = why
            self._st[L.S_SLOW_BAD] = float(int(self._st[L.S_SLOW_BAD]) | self._bits[i])

    def _valid(self, i: int, vals: dict) -> None:
        bits = 0
        for k, b in CHANNEL_BITS.items():
            if k in vals:
                bits |= b
        with self._bad_lock:
            self._bits[i] = bits
            self._why[i] = ""
            self._st[L.S_SLOW_BAD] = float(int(self._st[L.S_SLOW_BAD]) & ~bits)

    def set_points(self, omega_rpm: float, p_inj_bar: float) -> None:
        """Send Ω and P_I setpoints to every slow driver that takes them (returns at once)."""
        for d in self.drivers:
            threading.Thread(target=self._setpoint, args=(d, omega_rpm, p_inj_bar),
                             daemon=True).start()

    def _setpoint(self, d, omega, p) -> None:
        try:
            d.write_setpoints(omega_rpm=omega, p_inj_bar=p)
        except NotImplementedError:
            pass
        except Exception as exc:  # noqa: BLE001 - logged; the driver's poll reports outages
            self._log.error("slow driver setpoint failed", driver=d.name, error=str(exc))

    def _run(self, i: int, d, stop: threading.Event) -> None:
        period = 1.0 / self._hz[i]
        failed = False
        st = self._st
        while not stop.wait(period):
            try:
                vals = d.poll()
            except Exception as exc:  # noqa: BLE001 - device unreachable: a fault, once
                if not failed:
                    self._log.error("slow driver failed", driver=d.name, error=str(exc))
                    why = str(exc) or type(exc).__name__
                    self._invalid(i, why if why.startswith(d.name) else f"{d.name}: {why}")
                    self._requests.post(RQ.SLOW, FC.SLOW_DRIVER)
                failed = True
                continue
            if not vals:
                continue     # no values yet, no fault yet (the driver's own grace)
            failed = False
            self._since[i] = time.monotonic()
            self._polled[i] = True
            if "omega_rpm" in vals:
                st[L.S_SLOW_OMEGA] = float(vals["omega_rpm"])
            if "p_inj_bar" in vals:
                st[L.S_SLOW_PINJ] = float(vals["p_inj_bar"])
            self._valid(i, vals)     # after the values: a valid flag never shows an old one
