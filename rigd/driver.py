"""The driver interface and the driver registry (entry-point group ``rigd.drivers``).

Two kinds of driver exist:

* :class:`FastDriver` — exchanged with every cycle of the loop: ``read`` fills the input frame
  (see :mod:`rigd.frame`), ``write`` applies the four valve drive voltages. Must not block for
  longer than a fraction of the period; must not allocate per call.
* :class:`SlowDriver` — polled in its own thread at ``poll_hz`` (10–100 Hz): Modbus pressure,
  speed, regulator setpoints. The loop never waits for it; it reads the latest value.

Every driver has a lifecycle like ros2_control's hardware interface::

    unconfigured --configure()--> inactive --activate()--> active
    active --deactivate(safe)--> inactive --cleanup()--> unconfigured

``configure`` acquires the device (port, connection), ``activate`` lets the loop command it,
``deactivate`` takes the outputs to the safe state and stops commanding them (a fast driver
writes the safe drive it is given; the serial front-end is told to hold its own safe voltage),
``cleanup`` releases the device. The loop calls them in this order at open and close, and
``deactivate`` at once from a dying loop thread. Drivers override the ``on_*`` hooks; the
simple default keeps the older two-method interface working: ``on_configure`` calls
:meth:`Driver.open`, ``on_cleanup`` calls :meth:`Driver.close`, a fast driver's
``on_deactivate`` writes the safe drive, the others do nothing.

Drivers are found by name through the entry-point group ``rigd.drivers`` so that a third-party
driver installs as an ordinary package::

    [project.entry-points."rigd.drivers"]
    mydaq = "mypkg.daq:MyDaqDriver"
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from importlib.metadata import entry_points
from typing import Any, ClassVar

import numpy as np

from rigd.errors import InputError

GROUP = "rigd.drivers"

UNCONFIGURED, INACTIVE, ACTIVE = "unconfigured", "inactive", "active"


#: ``drv_status`` bits (input channel ``IN_STATUS``) every fast driver means the same by; the
#: loop names them in the fault list (:func:`rigd.loop.faults.status_words`). Bits 2-7 are the
#: device's own, bits 10-15 the driver's own (its :meth:`Driver.status_text` names them).
STATUS_ENCODER = 1 << 0      # encoder signal lost
STATUS_SENSOR = 1 << 1       # sensor / ADC fault
STATUS_TIMEOUT = 1 << 8      # no fresh frame within the driver's timeout
STATUS_DISCONNECT = 1 << 9   # the device is disconnected (the driver reconnects)
#: while one of these bits is set the frame holds no fresh data: the loop runs on the held
#: values and records the channels the driver provides as invalid (NaN; docs/data.md)
STATUS_NO_DATA = STATUS_TIMEOUT | STATUS_DISCONNECT


class Driver(ABC):  # noqa: B024 - abstract by intent: only FastDriver/SlowDriver are made
    """Common part of every driver.

    Parameters
    ----------
    options : dict
        The driver's own section of the rig config (validated by the driver's ``Options``
        pydantic model when it defines one).
    fs : float
        Loop rate, Hz.
    """

    kind: ClassVar[str] = "fast"
    name: ClassVar[str] = "driver"
    #: True for a driver that simulates the plant: its records say ``source: simulated``.
    simulated: ClassVar[bool] = False

    def __init__(self, options: dict[str, Any] | None = None, *, fs: float = 5000.0):
        self.options = options or {}
        self.fs = float(fs)
        #: "unconfigured", "inactive" or "active" (see module docstring)
        self.lifecycle = UNCONFIGURED

    # --- lifecycle transitions (called by the loop; override the on_* hooks) ---------------
    def configure(self) -> None:
        """unconfigured → inactive: acquire the device (no-op in any other state)."""
        if self.lifecycle == UNCONFIGURED:
            self.on_configure()
            self.lifecycle = INACTIVE

    def activate(self) -> None:
        """inactive → active: the loop may command the outputs (configures first if needed)."""
        self.configure()
        if self.lifecycle == INACTIVE:
            self.on_activate()
            self.lifecycle = ACTIVE

    def deactivate(self, safe_drive: np.ndarray | None = None) -> None:
        """active → inactive: outputs to the safe state, stop commanding them.

        Runs in: any thread, including a dying loop thread (the loop no longer cycles).
        ``safe_drive`` (float64[N_OUT], V) is the loop's safe-state drive.
        """
        if self.lifecycle == ACTIVE:
            self.lifecycle = INACTIVE
            self.on_deactivate(safe_drive)

    def cleanup(self) -> None:
        """→ unconfigured: deactivate if active, then release the device."""
        if self.lifecycle == ACTIVE:
            self.deactivate()
        if self.lifecycle == INACTIVE:
            self.lifecycle = UNCONFIGURED
            self.on_cleanup()

    # --- hooks (defaults: the two-method interface open/close) ----------------------------
    def on_configure(self) -> None:
        """Acquire the device. Default: :meth:`open`."""
        self.open()

    def on_activate(self) -> None:  # noqa: B027 - optional hook
        """Enable commanding the outputs. Default: nothing."""

    def on_deactivate(self, safe_drive: np.ndarray | None) -> None:  # noqa: B027
        """Outputs to the safe state. Default: nothing (a fast driver writes ``safe_drive``)."""

    def on_cleanup(self) -> None:
        """Release the device. Default: :meth:`close`."""
        self.close()

    def open(self) -> None:  # noqa: B027 - optional hook
        """Acquire the device (called once, before the loop starts)."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release the device; must leave outputs in a safe state."""

    def counters(self) -> dict[str, int]:
        """Error/health counters for status reports (CRC errors, timeouts, reconnects...)."""
        return {}

    #: words for this driver's own ``drv_status`` bits (bit value -> condition), used in the
    #: fault list beside the shared bits' (rigd.loop.faults.status_words)
    status_names: ClassVar[dict[int, str]] = {}

    def status_text(self, bits: int) -> str:
        """One line saying what this driver's ``drv_status`` bits mean, "" if it has no words
        for them (the fault then names the bits only). Runs in: any thread."""
        return ""


class FastDriver(Driver):
    """Per-cycle I/O: sensors in, valve drive voltages out."""

    kind = "fast"

    @abstractmethod
    def read(self, frame_in: np.ndarray) -> None:
        """Fill the ``IN_*`` slots this driver owns in ``frame_in`` (float64[N_IN]), in place.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """

    @abstractmethod
    def write(self, drive: np.ndarray) -> None:
        """Apply the drive voltages ``drive`` (float64[N_OUT], V) to the valves.

        Runs in: loop thread — O(1), allocation-free, non-blocking (as ``read``).
        """

    def on_deactivate(self, safe_drive: np.ndarray | None) -> None:
        """Write the safe drive (default; a device with its own safe hold may use that)."""
        if safe_drive is not None:
            self.write(safe_drive)

    def prepare_operating_point(self, omega_rpm: float, p_inj_bar: float):
        """Stage an operating-point change (Ω rpm, P_I bar), or None if not supported.

        Runs in: the caller's thread, never the loop thread: do every slow step here. Return
        a callable the loop runs at a cycle boundary, which must be O(1), allocation-free and
        non-blocking (e.g. copying a prepared parameter block). Default: None (the loop sends
        the setpoints to the slow drivers instead).
        """
        return None

    def plant_time_constant_s(self) -> float | None:
        """The plant's fastest closed-loop time constant, s, from the driver's nominal plant
        model (min over its modes of 1 / (ζ ω_n)), or None when it has none (default).

        The loop derives its stall and overrun-storm bounds from it (:mod:`rigd.loop.liveness`;
        ``supervisor.plant_tau_s`` overrides). Runs in: the caller's thread, once, before the
        loop starts.
        """
        return None


class SlowDriver(Driver):
    """Slow channels polled in their own thread."""

    kind = "slow"
    poll_hz: float = 20.0

    @abstractmethod
    def poll(self) -> dict[str, float]:
        """Read the slow channels; return ``{"omega_rpm": ..., "p_inj_bar": ...}`` etc.

        Runs in the driver's own thread, may block up to the device timeout. Raise
        :class:`rigd.errors.FaultError` when the device is unreachable. An empty dict means
        no values yet and no fault yet (the staleness clock keeps running).
        """

    def write_setpoints(self, **setpoints: float) -> None:  # noqa: B027 - optional
        """Send setpoints (e.g. ``p_inj_bar``, ``omega_rpm``) to regulators, if supported."""
        raise NotImplementedError(f"driver {self.name!r} takes no setpoints")


def available_drivers() -> dict[str, str]:
    """Names of installed drivers mapped to their ``module:Class`` targets."""
    return {ep.name: ep.value for ep in entry_points(group=GROUP)}


def driver_class(name: str) -> type[Driver]:
    """Load the driver class registered under ``name``.

    Raises
    ------
    InputError
        No driver of that name is installed, or it cannot be imported.
    """
    for ep in entry_points(group=GROUP):
        if ep.name == name:
            try:
                cls = ep.load()
            except Exception as exc:  # a broken third-party package must not crash us
                raise InputError(f"driver {name!r} ({ep.value}) failed to import: {exc}") from None
            if not (isinstance(cls, type) and issubclass(cls, Driver)):
                raise InputError(f"driver {name!r} ({ep.value}) is not a rigd.driver.Driver")
            return cls
    known = ", ".join(sorted(available_drivers())) or "none"
    raise InputError(f"unknown driver {name!r} (installed: {known})")


def data_source(fast: Driver, slow: Any = ()) -> dict[str, Any]:
    """Where a loop's data come from, for records and manifests.

    Returns
    -------
    dict
        ``{"source": "simulated" | "rig", "drivers": {"fast": name, "slow": [names]}}``:
        *simulated* when any driver simulates the plant (:attr:`Driver.simulated`), else the
        data come from the rig. ``rigd identify``/``compare``/``diagnose`` print it.
    """
    slow = list(slow or [])
    simulated = any(bool(getattr(d, "simulated", False)) for d in (fast, *slow))
    return {"source": "simulated" if simulated else "rig",
            "drivers": {"fast": str(getattr(fast, "name", type(fast).__name__)),
                        "slow": [str(getattr(d, "name", type(d).__name__)) for d in slow]}}
