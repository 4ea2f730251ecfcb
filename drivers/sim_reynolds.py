"""The physics-grade simulated rig: a FastDriver (entry point ``sim_reynolds``).

Compressible Reynolds film with four injecting valves and a flexible FE shaft (docs/plant.md,
"The physics-grade plant"). Same interface as the ``sim`` plant: ``kernel``/``state``/
``params`` for the lock-step runner, :meth:`read`/:meth:`write` for the real-time clock,
:meth:`set_operating_point`, :meth:`impact`, :meth:`reset`, :meth:`run`, :meth:`describe`.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
from pydantic import ValidationError

from rigd.driver import FastDriver
from rigd.errors import InputError
from rigd.frame import N_IN, N_OUT
from rigd_drivers import sim_physics as phys
from rigd_drivers import sim_reynolds_analysis as an
from rigd_drivers import sim_reynolds_kernel as k
from rigd_drivers import sim_reynolds_layout as L
from rigd_drivers.sim_reynolds_options import ReynoldsOptions
from rigd_drivers.sim_reynolds_params import param_block


def _fmt_loc(loc: tuple) -> str:
    return ".".join(str(p) if not isinstance(p, int) else f"[{p}]" for p in loc)


class ReynoldsPlantDriver(FastDriver):
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

    def __init__(self, options: dict[str, Any] | ReynoldsOptions | None = None,
                 fs: float = 5000.0):
        if isinstance(options, ReynoldsOptions):
            opts = options
        else:
            try:
                opts = ReynoldsOptions.model_validate(options or {})
            except ValidationError as exc:
                err = exc.errors()[0]
                msg = "unknown key" if err["type"] == "extra_forbidden" else err["msg"]
                if "input" in err and not isinstance(err["input"], (dict, list)) \
                        and err["type"] != "extra_forbidden":
                    msg += f" (got {err['input']!r})"
                raise InputError(msg, f"drivers.fast.options.{_fmt_loc(err['loc'])}") from None
        if not (math.isfinite(fs) and 100.0 <= fs <= 100_000.0):
            raise InputError(f"loop rate must be in [100, 100000] Hz (got {fs!r})", "fs")
        super().__init__(opts.model_dump(), fs=fs)
        self.opts = opts
        self.kernel = k.plant_step
        self._lock = threading.Lock()           # impact hammer requests
        self._stage_lock = threading.Lock()     # staged parameter block writers
        self._omega = opts.omega_rpm
        self._p_inj = opts.p_inj_bar
        self._arr = an.make_arrays(opts, fs)
        self.params = self._arr.params
        self.state = self._arr.state
        self._out = np.zeros(N_IN)
        o = self._arr.lay.st[L.T_FRAME]
        self._frame_view = self.state[o:o + N_IN]
        stg = int(self.params[L.H_STG])
        self._staged_view = self.params[stg:stg + int(self.params[L.H_NA])]
        self.reset()

    # --- FastDriver --------------------------------------------------------------------
    def read(self, frame_in: np.ndarray) -> None:
        """Copy the current sensor frame into ``frame_in``."""
        np.copyto(frame_in, self._frame_view)

    def write(self, drive: np.ndarray) -> None:
        """Apply the four drive voltages for one period (runs the kernel once)."""
        self.kernel(self.state, self.params, drive, self._out)

    # --- plant control ------------------------------------------------------------------
    def reset(self, drive_v: float | None = None) -> None:
        """Put the plant at rest under a constant drive (film at its steady state, journal at
        the force equilibrium). Not thread-safe with a running loop."""
        v0 = self.opts.valves.initial_drive_v if drive_v is None else float(drive_v)
        seq = self.params[L.H_STAGE_SEQ]
        self._arr.set_block(self._omega, self._p_inj)
        self.params[L.H_STAGE_SEQ] = seq
        an.rest(self._arr, v0)
        k.plant_sense(self.state, self.params, self._out)

    def set_operating_point(self, omega_rpm: float, p_inj_bar: float) -> None:
        """Change Ω (rpm) and P_I (bar); thread-safe, swapped in whole at the next step.

        The supply pressure steps; film and shaft carry on from their current state.
        """
        self.prepare_operating_point(omega_rpm, p_inj_bar)()

    def prepare_operating_point(self, omega_rpm: float, p_inj_bar: float):
        """Build the parameter block of (Ω rpm, P_I bar) now; return its O(1) swap.

        Runs in: the caller's thread (shaft step matrices, allocations). The returned callable
        stages the block under the sequence lock (one copy into a preallocated view); the
        kernel swaps it in whole at the start of its next step.

        Raises
        ------
        InputError
            Operating point outside Ω ∈ [0, 6000] rpm, P_I ∈ [3, 7] bar.
        """
        try:
            phys.check_operating_point(float(omega_rpm), float(p_inj_bar))
        except (TypeError, ValueError) as exc:
            raise InputError(str(exc), "set_operating_point") from None
        block = param_block(self.opts, self._arr.lay, self._arr.shaft, float(omega_rpm),
                            float(p_inj_bar), self.fs)
        point = (float(omega_rpm), float(p_inj_bar))
        params, staged, lock = self.params, self._staged_view, self._stage_lock

        def swap() -> None:
            """Stage the prepared block (loop thread: O(1), no allocation, no wait)."""
            with lock:
                seq = params[L.H_STAGE_SEQ]
                params[L.H_STAGE_SEQ] = seq + 1.0          # odd: writing
                np.copyto(staged, block)
                params[L.H_STAGE_SEQ] = seq + 2.0          # even: complete
                self._omega, self._p_inj = point

        return swap

    @property
    def operating_point(self) -> tuple[float, float]:
        """(Ω rpm, P_I bar) last set."""
        return self._omega, self._p_inj

    def impact(self, axis: str, peak_n: float, duration_s: float) -> None:
        """Half-sine hammer pulse on the disc along ``axis`` (x or y), from the next step."""
        if axis not in ("x", "y"):
            raise InputError(f"impact axis must be 'x' or 'y' (got {axis!r})", "impact")
        if not (math.isfinite(peak_n) and abs(peak_n) <= 1000.0):
            raise InputError(f"impact peak must be within ±1000 N (got {peak_n!r})", "impact")
        T = 1.0 / self.fs
        if not (math.isfinite(duration_s) and 2 * T <= duration_s <= 0.1):
            raise InputError(f"impact duration must be in [{2 * T:g}, 0.1] s "
                             f"(got {duration_s!r})", "impact")
        with self._lock:
            self.params[L.H_IMP_AXIS] = 0.0 if axis == "x" else 1.0
            self.params[L.H_IMP_PEAK] = float(peak_n)
            self.params[L.H_IMP_DUR] = float(duration_s)
            self.params[L.H_IMP_SEQ] += 1.0

    def run(self, drives: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
        """Open-loop batch: apply ``drives`` (n, 4) V, return the sensor frames (n, N_IN)."""
        drives = np.ascontiguousarray(drives, dtype=float)
        if drives.ndim != 2 or drives.shape[1] != N_OUT:
            raise InputError(f"drives must have shape (n, {N_OUT}) (got {drives.shape})", "run")
        if frames is None:
            frames = np.zeros((drives.shape[0], N_IN))
        k.run_batch(self.state, self.params, drives, frames)
        return frames

    def counters(self) -> dict[str, int]:
        """Sub-steps whose Newton update did not reach 1e-6 p_a (health of the solver)."""
        return {"newton_not_converged": int(self._arr.stsc[L.ST_FAIL])}

    def linear_modes(self, drive_v: float | None = None) -> an.LinearModes:
        """Modes of the linearised plant at rest at the current operating point (≈ 1 s)."""
        v0 = self.opts.valves.initial_drive_v if drive_v is None else float(drive_v)
        arr = an.make_arrays(self.opts, self.fs, self._omega, self._p_inj)
        an.rest(arr, v0)
        return an.linear_modes(arr, an.valve_area_fractions(self.opts, v0))

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
        }
