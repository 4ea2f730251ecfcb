"""Liveness bounds of the real-time loop, derived from the plant (docs/loop.md "Liveness").

A stall matters to the plant when the loop is absent for as long as the plant needs to move
away from where the loop holds it. While the loop stands, the drive outputs are held at their
last values; each valve — under its PD loop normally — is then an open-loop stable,
overdamped second-order system that settles on the held drive, so the valves do not run away.
What loses its control is the shaft in the bearing: its motion evolves with the plant's modes
and nothing corrects it. The time scale on which that matters is the plant's **fastest
closed-loop time constant** τ = min over its modes of 1 / (ζ ω_n) (the decay time of the
fastest envelope; ``supervisor.plant_tau_s``, or the fast driver's nominal plant model:
:meth:`rigd.driver.FastDriver.plant_time_constant_s`).

* **Stall** (``loop_stall``): one gap between two cycles longer than the stall bound
  ``supervisor.stall_s`` (default τ: the shaft went a whole time constant without control).
  Measured by the cycle itself when it runs again (:func:`rigd.loop.cycle.watch_cycle`) and,
  while it stands, by the watchdog process (:mod:`rigd.service.watchdog`) through the SAFE
  word — so the fault is latched even when the loop cannot latch it itself.
* **Overrun storm** (``overrun_storm``): the same loss in pieces. Every gap beyond one period
  is control time lost (outputs held); the losses go into a leaky bucket of time constant
  ``overrun_storm_window_s`` (default 10 τ: the horizon over which the plant still carries the
  effect of a missed correction, e^-10 of it is left after) and the fault latches when the
  bucket holds more than ``overrun_storm_lost_s`` (default: the stall bound) — the loop lost,
  within the plant's memory, as much control as one stall that matters. Late cycles that are
  late by microseconds add microseconds; a busy machine's jitter does not trip it, a loop that
  is absent for a tenth of the time does. (A config that sets the former
  ``overrun_storm_count`` gets the count rule instead: that many overruns within the window.)
* Neither is measured during the loop's first :data:`GRACE_S` (its start-up transient), nor
  is the count rule (:mod:`rigd.loop.realtime`).
* **A simulated plant** (the fast driver's ``plant_clock`` is ``"cycle"``: one plant step per
  loop cycle) does not move while the loop stands — its time is the loop's — so no stall costs
  it anything, and τ says nothing about what matters. What still matters is the service: an
  operator's view and the commands wait on the loop. Its bound is :data:`SERVICE_STALL_S`
  (a frozen loop is a fault within a second, as the console's and ``status``'s freshness
  promises), and the overrun storm is the same loss in pieces within ``10 ×`` that window.
  A busy desktop that delays a simulated loop by tens of milliseconds is then no fault; a
  SIGSTOP of a second and more is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rigd.loop import layout as L

#: τ when neither the config nor the fast driver gives one, s (a plant of ≈ 100 Hz modes with
#: ζ ≈ 0.08; set ``supervisor.plant_tau_s`` for a real plant)
DEFAULT_TAU_S = 0.02
#: overrun-storm bucket time constant, in plant time constants
STORM_WINDOW_TAUS = 10.0
#: the loop's first cycles are not measured, s: the start-up transient (first calls of every
#: code path, the service's processes starting; K∞ is off until enabled) is no stall
GRACE_S = 0.5
#: the stall bound of a simulated plant (``plant_clock == "cycle"``): the service's, s
SERVICE_STALL_S = 1.0


@dataclass(frozen=True)
class LivenessBounds:
    """The derived bounds (s) and where τ came from.

    Attributes
    ----------
    tau_s : float
        The plant's fastest closed-loop time constant, s.
    tau_source : str
        ``"config"``, ``"driver"`` (its nominal plant model) or ``"default"``.
    stall_s : float
        A gap between cycles longer than this latches ``loop_stall`` (0: off), s.
    storm_window_s : float
        Time constant of the lost-control-time bucket, s.
    storm_lost_s : float
        Bucket content that latches ``overrun_storm`` (0: off), s.
    """

    tau_s: float
    tau_source: str
    stall_s: float
    storm_window_s: float
    storm_lost_s: float

    def as_dict(self) -> dict:
        return {"plant_tau_s": self.tau_s, "plant_tau_source": self.tau_source,
                "stall_s": self.stall_s, "storm_window_s": self.storm_window_s,
                "storm_lost_s": self.storm_lost_s}


def derive(supervisor, fast_driver=None) -> LivenessBounds:
    """The bounds from ``supervisor`` (:class:`rigd.rigconfig.SupervisorConfig`) and the fast
    driver's nominal plant model (module docstring)."""
    tau, source = supervisor.plant_tau_s, "config"
    if tau is None:
        get = getattr(fast_driver, "plant_time_constant_s", None)
        tau = get() if callable(get) else None
        source = "driver"
        if tau is None or not (math.isfinite(tau) and tau > 0):
            tau, source = DEFAULT_TAU_S, "default"
    tau = float(tau)
    # the scale on which a stall matters: the plant's τ, or the service's for a plant that
    # advances with the loop's cycles (module docstring)
    scale = (SERVICE_STALL_S if getattr(fast_driver, "plant_clock", "wall") == "cycle"
             else tau)
    stall = scale if supervisor.stall_s is None else float(supervisor.stall_s)
    window = (STORM_WINDOW_TAUS * scale if supervisor.overrun_storm_window_s is None
              else float(supervisor.overrun_storm_window_s))
    if supervisor.overrun_storm_lost_s is not None:
        lost = float(supervisor.overrun_storm_lost_s)
    elif supervisor.overrun_storm_count is not None:
        lost = 0.0        # the former count rule is configured: it replaces this one
    else:
        lost = stall
    return LivenessBounds(tau, source, stall, window, lost)


def fill(prm, bounds: LivenessBounds, fs: float) -> None:
    """Write the bounds into the kernel's parameters (before the cycles start)."""
    period = 1.0 / fs
    prm[L.P_PERIOD_NS] = period * 1e9
    prm[L.P_STALL_NS] = bounds.stall_s * 1e9
    prm[L.P_LOST_DECAY] = math.exp(-period / bounds.storm_window_s)
    prm[L.P_STORM_NS] = bounds.storm_lost_s * 1e9
    prm[L.P_GRACE_N] = round(GRACE_S * fs)
