"""The physics-grade simulated rig: a FastDriver (entry point ``sim_reynolds``).

Compressible Reynolds film with four injecting valves and a flexible FE shaft (docs/plant.md,
"The physics-grade plant"). Same interface as the ``sim`` plant: ``kernel``/``state``/
``params`` for the lock-step runner, :meth:`read`/:meth:`write` for the real-time clock,
:meth:`set_operating_point`, :meth:`impact`, :meth:`reset`, :meth:`run`, :meth:`describe`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rigd.frame import N_IN
from rigd_drivers.plant import physics as phys
from rigd_drivers.plant.base import SimulatedPlantDriver
from rigd_drivers.reynolds import analysis as an
from rigd_drivers.reynolds import kernel as k
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds import linear
from rigd_drivers.reynolds.options import ReynoldsOptions
from rigd_drivers.reynolds.params import param_block


class ReynoldsPlantDriver(SimulatedPlantDriver):
    """Physics-grade simulated plant driver.

    Parameters
    ----------
    options : dict or ReynoldsOptions, optional
        ``drivers.fast.options`` of the config (see :class:`ReynoldsOptions`).
    fs : float
        Loop rate, Hz: one :meth:`write` advances the plant by 1/fs.
    """

    name = "sim_reynolds"
    simulated = True            # its records say source: simulated
    Options = ReynoldsOptions
    options_where = "drivers.fast.options."
    _kmod = k
    _hdr = L

    def __init__(self, options: dict[str, Any] | ReynoldsOptions | None = None,
                 fs: float = 5000.0):
        super().__init__(options, fs)
        self._arr = an.make_arrays(self.opts, fs)
        self.params = self._arr.params
        self.state = self._arr.state
        o = self._arr.lay.st[L.T_FRAME]
        self._frame_view = self.state[o:o + N_IN]
        self._stage_start = int(self.params[L.H_STG])
        self.reset()

    # --- plant control ------------------------------------------------------------------
    def reset(self, drive_v: float | None = None) -> None:
        """Put the plant at rest under a constant drive (film and chambers at their steady
        state, journal at the equilibrium under the static load). Not thread-safe with a
        running loop."""
        v0 = self.opts.valves.initial_drive_v if drive_v is None else float(drive_v)
        seq = self.params[L.H_STAGE_SEQ]
        self._arr.set_block(self._omega, self._p_inj)
        self.params[L.H_STAGE_SEQ] = seq
        an.rest(self._arr, v0)
        k.plant_sense(self.state, self.params, self._out)
        self._rest = an.rest_position(self._arr)

    def _param_block(self, omega_rpm: float, p_inj_bar: float) -> np.ndarray:
        """The parameter block of (Ω rpm, P_I bar) (shaft step matrices, allocations)."""
        return param_block(self.opts, self._arr.lay, self._arr.shaft, omega_rpm, p_inj_bar,
                           self.fs)

    def counters(self) -> dict[str, Any]:
        """Health of the solver since the last :meth:`reset` (``rigd ctl status`` shows it).

        ``substeps`` integrated; ``newton_iterations`` over them; ``newton_not_converged``:
        sub-steps whose residual after the last update stayed above ``newton_tolerance``
        after ``newton_max_iterations``; ``non_finite``: sub-steps whose solution was not
        finite; ``h_floor``: sub-steps ending with the film thickness floored (0.02 c, ε >
        0.98); ``p_floor``: sub-steps with a pressure clipped at 0.2 p_a; ``eps_max``: the
        largest journal eccentricity ratio; ``stopped``: "" or why the plant stopped
        (contact / not finite) and ``stopped_at_seq`` the sample.
        """
        sc = self._arr.stsc
        bits = int(sc[L.ST_STOP])
        return {"substeps": int(sc[L.ST_NSUB]), "newton_iterations": int(sc[L.ST_NEWTON_IT]),
                "newton_not_converged": int(sc[L.ST_FAIL]), "non_finite": int(sc[L.ST_NAN]),
                "h_floor": int(sc[L.ST_HFLOOR]), "p_floor": int(sc[L.ST_PFLOOR]),
                "eps_max": round(float(sc[L.ST_EPS_MAX]), 4),
                "stopped": self.status_text(bits),
                "stopped_at_seq": int(sc[L.ST_STOP_SEQ]) if bits else None}

    def status_text(self, bits: int) -> str:
        """What this plant's ``drv_status`` bits mean (one line, "" for 0)."""
        out = []
        if bits & L.STATUS_CONTACT:
            out.append("contact: the journal reached the bearing wall (eccentricity ratio ≥ 1); "
                       "the simulated plant stopped at the last state before it and stays "
                       "there until the driver is reset (restart the loop)")
        if bits & L.STATUS_DIVERGED:
            out.append("the simulated plant's film + shaft solution was not finite; it stopped "
                       "at the last finite state until the driver is reset (restart the loop)")
        rest = bits & ~(L.STATUS_CONTACT | L.STATUS_DIVERGED)
        if rest:
            out.append(f"status bits {rest:#x}")
        return "; ".join(out)

    def linear_modes(self, drive_v: float | None = None) -> linear.LinearModes:
        """Modes of the linearised plant at rest at the current operating point (≈ 1 s)."""
        v0 = self.opts.valves.initial_drive_v if drive_v is None else float(drive_v)
        arr = an.make_arrays(self.opts, self.fs, self._omega, self._p_inj)
        an.rest(arr, v0)
        return linear.linear_modes(arr, an.valve_area_fractions(self.opts, v0))

    def describe(self) -> dict[str, Any]:
        """Operating point, options and structural data (cheap: no film solve)."""
        sh = self._arr.shaft
        return {
            "plant": "sim_reynolds", "omega_rpm": self._omega, "p_inj_bar": self._p_inj,
            "fs": self.fs, "grid": self.opts.grid.model_dump(), "substeps": self.opts.substeps,
            "shaft_modes_hz": (sh.omega_r / (2 * math.pi)).tolist(),
            "bearing": self.opts.bearing.model_dump(),
            "valves": [vars(v) for v in phys.valve_params(self.opts.valves.f_scale)],
            "pd_suggested": {"kp": phys.PD_KP, "kd": phys.PD_KD, "tau_d": phys.PD_TAU_D},
            "effects_enabled": [], "seed": self.opts.seed,
            "noise": self.opts.noise.model_dump(),
            "feed": self.opts.feed.model_dump(), "load": self.opts.load.model_dump(),
            # the last reset's rest state: disc (sensor) position, µm — the supervisor's
            # centre — and the journal's eccentricity (x_b, y_b)/c
            "rest_um": self._rest["disc_um"], "rest_eccentricity": self._rest["eccentricity"],
        }
