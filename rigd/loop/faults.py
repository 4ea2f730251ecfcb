"""Fault codes of the supervisor: stable numbers and names (recorded in the ``fault`` channel).

Any violation puts the loop into the *safe state* within the cycle that detects it: K∞ output
off, excitation off, valve references r_p,i = r0, the PD loops keep holding the valves there.
The code is LATCHED (the first fault wins) until an explicit ``ControlLoop.reset_fault()``; a
reset while the cause persists latches again on the next cycle. A fault of another kind that
occurs while one is latched does not replace it, but it is listed too (once per kind until the
reset: ``faults()``, the fault list of ``status``), so an outage during a SAFE is never hidden.

The numbers are part of the recording format and of the service protocol: never renumber,
only append.
"""

from __future__ import annotations

from rigd.driver import (  # noqa: F401 - the shared bit meanings, used by the cycle
    STATUS_DISCONNECT,
    STATUS_ENCODER,
    STATUS_NO_DATA,
    STATUS_SENSOR,
    STATUS_TIMEOUT,
)

NONE = 0
SENSOR_NAN = 1          # a sensor channel (e_x, e_y, y_p1..4, phi) is NaN or infinite
SENSOR_RANGE = 2        # e_x/e_y or y_p,i outside the configured sensor range
STALE_FRAME = 3         # the fast driver's frame counter (drv_seq) repeated too long
ENCODER_LOST = 4        # phi frozen while Ω > threshold, or driver status bit ENCODER
VALVE_TRACKING = 5      # |r_p,i - y_p,i| above the limit for longer than allowed
SHAFT_DISPLACEMENT = 6  # radial shaft displacement beyond the allowed fraction of the film gap
OVERRUN_STORM = 7       # too much control time lost to late/skipped cycles (rigd.loop.liveness)
DRIVER_EXCEPTION = 8    # a driver raised in read/write (Python side)
DRIVER_STATUS = 9       # the fast driver reported a fault status bit (other than encoder)
RECORDER_OVERFLOW = 10  # the recorder ring buffer was full: frames could not be recorded
SLOW_DRIVER = 11        # a slow driver failed (device unreachable) or its data went stale
OPERATOR_STOP = 12      # safe state requested by the operator / service
LOOP_DIED = 13          # the loop thread died or a cycle raised: outputs set safe, loop stopped
OPERATOR_SAFE = 14      # the operator's safe-state button (`rigd ctl safe`, the console)
LOOP_STALL = 15         # no cycle for longer than the stall bound (loop or watchdog saw it)

#: code -> (name, one-line explanation)
FAULTS: dict[int, tuple[str, str]] = {
    NONE: ("none", "no fault"),
    SENSOR_NAN: ("sensor_nan", "a sensor channel is NaN or infinite"),
    SENSOR_RANGE: ("sensor_range", "a sensor channel is outside its configured range"),
    STALE_FRAME: ("stale_frame", "the fast driver delivered the same frame repeatedly"),
    ENCODER_LOST: ("encoder_lost",
                   "encoder angle frozen while the shaft turns, or encoder status bit"),
    VALVE_TRACKING: ("valve_tracking", "a valve stayed far from its reference for too long"),
    SHAFT_DISPLACEMENT: ("shaft_displacement",
                         "shaft displacement beyond the allowed fraction of the 25 um film gap"),
    OVERRUN_STORM: ("overrun_storm",
                    "the loop lost as much control time (periods with no cycle) within the "
                    "plant's memory as one stall that matters"),
    DRIVER_EXCEPTION: ("driver_exception", "a driver raised an exception"),
    DRIVER_STATUS: ("driver_status", "the fast driver reported a fault status"),
    RECORDER_OVERFLOW: ("recorder_overflow",
                        "recording failed or recorder ring buffer full: frames not recorded"),
    SLOW_DRIVER: ("slow_driver", "a slow driver failed or its data went stale"),
    OPERATOR_STOP: ("operator_stop", "safe state requested by the operator"),
    LOOP_DIED: ("loop_died",
                "the loop thread died or a cycle raised; outputs set safe, loop stopped"),
    OPERATOR_SAFE: ("operator_safe",
                    "safe state requested by the operator (safe command); reset to leave it"),
    LOOP_STALL: ("loop_stall",
                 "the loop stood still longer than its stall bound (no cycle ran)"),
}

#: fast-driver status bits (``drv_status`` input channel; rigd.driver): any bit is a fault

#: words for the shared bits; the others are the device's or the driver's own
#: (:meth:`rigd.driver.Driver.status_text`)
STATUS_WORDS: dict[int, str] = {
    STATUS_ENCODER: "encoder signal lost",
    STATUS_SENSOR: "sensor/ADC fault",
    STATUS_TIMEOUT: "no frame within the driver's timeout",
    STATUS_DISCONNECT: "the device is disconnected (reconnecting)",
}

#: input-frame channel names used as fault details (index into rigd.frame.IN_NAMES)


def fault_name(code: int) -> str:
    """Stable short name of a fault code (``"unknown_<n>"`` for an unknown code)."""
    return FAULTS.get(int(code), (f"unknown_{int(code)}", ""))[0]


def fault_text(code: int) -> str:
    """One-line explanation of a fault code."""
    return FAULTS.get(int(code), ("", f"unknown fault code {int(code)}"))[1]


def describe(code: int, detail: int, own: dict[int, str] | None = None) -> str:
    """Human text for a latched fault with its detail (channel or valve index; the status
    bits of ``driver_status``, in words: ``own`` are the fast driver's words for its bits)."""
    from rigd.frame import IN_NAMES

    code, detail = int(code), int(detail)
    text = fault_text(code)
    if detail >= 0:
        if code in (SENSOR_NAN, SENSOR_RANGE):
            name = IN_NAMES[detail] if detail < len(IN_NAMES) else str(detail)
            text += f" (channel {name})"
        elif code == VALVE_TRACKING:
            text += f" (valve {detail + 1})"
        elif code == DRIVER_STATUS:
            text += f": {status_words(detail, own)}"
    return text


def status_words(bits: int, own: dict[int, str] | None = None) -> str:
    """The conditions the ``drv_status`` ``bits`` name, in words, ``"; "``-separated: the
    shared bits (:data:`STATUS_WORDS`), then ``own`` (a driver's words for its bits), then
    any bit nobody names as ``device status bit n``."""
    bits = int(bits)
    words = {**STATUS_WORDS, **(own or {})}
    out = [words.get(1 << b, f"device status bit {b}") for b in range(32) if bits & (1 << b)]
    return "; ".join(out) if out else "no status bit"
