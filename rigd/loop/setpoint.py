"""The operating-point set-point: what ``operating_point.set`` (``rigd ctl op``) last applied.

The loop's ``status`` reports it as ``set_point`` beside the measured ``last_frame`` Ω and
P_I (the rig follows a set-point at its own pace), so that a client — the web console's
operating-point form — shows what the rig was told, not only where it is.

A set-point whose command is queued to the loop (the simulated plant's prepared parameter
block) counts once the loop has applied it (its ticket says so); a command the loop dropped
(overtaken by SAFE, too late) never becomes the set-point. A set-point handed to the slow
drivers (a real rig's regulators) counts at once. The loop thread never touches this object:
the ticket is read in the thread asking for ``status``.
"""

from __future__ import annotations

import threading
from typing import Any


class SetPoint:
    """The last applied operating point (Ω rpm, P_I bar) and the ones still queued.

    Parameters
    ----------
    initial : tuple of float, optional
        ``(omega_rpm, p_inj_bar)`` in force at start (the simulated plant's configured
        operating point); None when unknown (a rig before its first ``op``).
    """

    def __init__(self, initial: tuple[float, float] | None = None) -> None:
        self._lock = threading.Lock()
        self._current = None if initial is None else (float(initial[0]), float(initial[1]))
        self._source = "config" if initial is not None else None
        self._pending: list[tuple[Any, float, float]] = []

    def queued(self, ticket: Any, omega_rpm: float, p_inj_bar: float) -> None:
        """A set-point posted to the loop with ``ticket`` (it counts once applied)."""
        with self._lock:
            self._pending.append((ticket, float(omega_rpm), float(p_inj_bar)))

    def applied(self, omega_rpm: float, p_inj_bar: float) -> None:
        """A set-point in force now (handed to the slow drivers)."""
        with self._lock:
            self._current = (float(omega_rpm), float(p_inj_bar))
            self._source = "op"

    def status(self) -> dict[str, Any] | None:
        """``{"omega_rpm", "p_inj_bar", "source"}`` (``source``: ``"config"`` — the start-up
        operating point — or ``"op"``), None when no set-point is known."""
        with self._lock:
            keep = []
            for ticket, om, pi in self._pending:      # in the order the loop applies them
                if ticket.applied:
                    self._current, self._source = (om, pi), "op"
                elif not ticket.dropped:
                    keep.append((ticket, om, pi))
            self._pending = keep
            if self._current is None:
                return None
            return {"omega_rpm": self._current[0], "p_inj_bar": self._current[1],
                    "source": self._source}
