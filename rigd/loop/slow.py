"""Slow-driver pollers: one thread per slow driver, latest values posted into the kernel state.

Each thread polls its driver at ``poll_hz`` and writes Ω and P_I into ``st[S_SLOW_OMEGA]`` /
``st[S_SLOW_PINJ]`` (one writer per slot: the thread of the driver that provides it); a
failing poll requests ``slow_driver`` once per outage. Setpoints are sent from short-lived
threads so no caller waits on a device.
"""

from __future__ import annotations

import threading
import time

from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop import requests as RQ


class SlowPollers:
    """Owner of the slow drivers' threads (see module docstring)."""

    def __init__(self, drivers, poll_hz, st, requests, log) -> None:
        self.drivers = list(drivers)
        self._hz = list(poll_hz) or [getattr(d, "poll_hz", 20.0) for d in self.drivers]
        self._st = st
        self._requests = requests
        self._log = log
        self._last_ok: list[float] = []
        self._threads: list[threading.Thread] = []

    def start(self, stop: threading.Event) -> None:
        now = time.monotonic()
        for i, d in enumerate(self.drivers):
            self._last_ok.append(now)
            t = threading.Thread(target=self._run, args=(i, d, stop), name=f"rigd-slow-{i}",
                                 daemon=True)
            t.start()
            self._threads.append(t)

    @property
    def native_ids(self) -> list[int]:
        return [t.native_id for t in self._threads]

    def stale(self, stale_s: float) -> bool:
        """True if a driver had no good poll for ``stale_s`` (its timer restarts: one report)."""
        now = time.monotonic()
        hit = False
        for i, t in enumerate(self._last_ok):
            if now - t > stale_s:
                self._last_ok[i] = now
                hit = True
        return hit

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
                    self._requests.post(RQ.SLOW, FC.SLOW_DRIVER)
                failed = True
                continue
            failed = False
            self._last_ok[i] = time.monotonic()
            if "omega_rpm" in vals:
                st[L.S_SLOW_OMEGA] = float(vals["omega_rpm"])
            if "p_inj_bar" in vals:
                st[L.S_SLOW_PINJ] = float(vals["p_inj_bar"])
