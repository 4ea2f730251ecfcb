"""The simulated rotor-gas bearing rig: a :class:`rigd.driver.FastDriver` (entry point ``sim``).

Four piezo valves (drive voltage → position, second order, optional hysteresis and creep), the
lumped 2-DOF bearing of Eq. 4 with M, D, G, K, B_p depending on the operating point
(Ω, P_I) (see :mod:`rigd_drivers.sim_physics`), encoder angle, optional run-out and mass
unbalance, sensor noise, an impact hammer, and hidden effects switched on in ``plant.effects``.

The compiled kernel (:func:`rigd_drivers.sim_kernel.plant_step`) is exposed as
``driver.kernel`` with its arrays ``driver.state`` and ``driver.params`` so that the lock-step
runner can call it from its own compiled loop; :meth:`read`/:meth:`write` use the same kernel.
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
from rigd_drivers import sim_kernel as k
from rigd_drivers import sim_physics as phys
from rigd_drivers.sim_options import PlantOptions
from rigd_drivers.sim_params import param_block, rest_state


def _fmt_loc(loc: tuple) -> str:
    return ".".join(str(p) if not isinstance(p, int) else f"[{p}]" for p in loc)


class SimPlantDriver(FastDriver):
    """Simulated plant driver.

    Parameters
    ----------
    options : dict or PlantOptions, optional
        The ``plant:`` section of the sim config (see :class:`PlantOptions`).
    fs : float
        Loop rate, Hz: one :meth:`write` (one kernel call) advances the plant by 1/fs.

    Attributes
    ----------
    kernel : numba dispatcher
        ``plant_step(state, params, drive, frame_in)``.
    state, params : ndarray
        float64 arrays of the kernel, mutated in place.
    """

    name = "sim"
    simulated = True
    Options = PlantOptions

    def __init__(self, options: dict[str, Any] | PlantOptions | None = None,
                 fs: float = 5000.0):
        if isinstance(options, PlantOptions):
            opts = options
        else:
            try:
                opts = PlantOptions.model_validate(options or {})
            except ValidationError as exc:
                err = exc.errors()[0]
                msg = "unknown key" if err["type"] == "extra_forbidden" else err["msg"]
                if "input" in err and not isinstance(err["input"], (dict, list)) \
                        and err["type"] != "extra_forbidden":
                    msg += f" (got {err['input']!r})"
                raise InputError(msg, f"plant.{_fmt_loc(err['loc'])}") from None
        if not (math.isfinite(fs) and 100.0 <= fs <= 100_000.0):
            raise InputError(f"loop rate must be in [100, 100000] Hz (got {fs!r})", "fs")
        super().__init__(opts.model_dump(), fs=fs)
        self.opts = opts
        self.kernel = k.plant_step
        self._lock = threading.Lock()           # impact hammer requests
        self._stage_lock = threading.Lock()     # staged parameter block writers
        self._omega = opts.omega_rpm
        self._p_inj = opts.p_inj_bar
        self.params = np.zeros(k.N_PARAMS)
        self.state = np.zeros(k.N_STATE)
        self._out = np.zeros(N_IN)
        self._frame_view = self.state[k.S_FRAME:k.S_FRAME + N_IN]
        self._staged_view = self.params[k.STG:k.STG + k.NA]
        self.reset()

    # --- FastDriver --------------------------------------------------------------------
    def read(self, frame_in: np.ndarray) -> None:
        """Copy the current sensor frame (e_x … drv_status) into ``frame_in``.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        np.copyto(frame_in, self._frame_view)

    def write(self, drive: np.ndarray) -> None:
        """Apply the four drive voltages for one period (runs the kernel once).

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        self.kernel(self.state, self.params, drive, self._out)

    # --- plant control ------------------------------------------------------------------
    def reset(self, drive_v: float | None = None) -> None:
        """Put the plant at rest under a constant drive (default ``valves.initial_drive_v``).

        Not thread-safe with a running loop: call before the loop starts. Time, angle and the
        noise stream restart from zero.
        """
        v0 = self.opts.valves.initial_drive_v if drive_v is None else float(drive_v)
        block = param_block(self.opts, self._omega, self._p_inj, self.fs)
        self.params[:] = 0.0
        self.params[k.ACT:k.ACT + k.NA] = block
        self.params[k.STG:k.STG + k.NA] = block
        self.state[:] = rest_state(self.opts, block, self._omega, self._p_inj, v0)
        k.plant_sense(self.state, self.params, self._out)

    def set_operating_point(self, omega_rpm: float, p_inj_bar: float) -> None:
        """Change Ω (rpm) and P_I (bar); safe to call from another thread while the loop runs.

        The new parameter set is staged and swapped in whole by the kernel at the start of
        its next step (sequence lock: never a torn set). Shaft and valve states carry on.

        Raises
        ------
        InputError
            Operating point outside Ω ∈ [0, 6000] rpm, P_I ∈ [3, 7] bar.
        """
        self.prepare_operating_point(omega_rpm, p_inj_bar)()

    def prepare_operating_point(self, omega_rpm: float, p_inj_bar: float):
        """Build the parameter block of (Ω rpm, P_I bar) now; return its O(1) swap.

        Runs in: the caller's thread (two matrix exponentials and allocations: never the
        loop thread). The returned callable stages the prepared block under the sequence lock
        (one copy of a fixed-size block into a preallocated view); the kernel swaps it in
        whole at the start of its next step. While a loop owns this driver, change the
        operating point through the loop (``ControlLoop.set_operating_point``), which runs
        the callable at a cycle boundary.

        Raises
        ------
        InputError
            Operating point outside Ω ∈ [0, 6000] rpm, P_I ∈ [3, 7] bar.
        """
        try:
            phys.check_operating_point(float(omega_rpm), float(p_inj_bar))
        except (TypeError, ValueError) as exc:
            raise InputError(str(exc), "set_operating_point") from None
        block = param_block(self.opts, float(omega_rpm), float(p_inj_bar), self.fs)
        point = (float(omega_rpm), float(p_inj_bar))
        params, staged, lock = self.params, self._staged_view, self._stage_lock

        def swap() -> None:
            """Stage the prepared block. Runs in: loop thread — O(1), no allocation, no wait
            (the stage lock has no other holder while a loop owns the driver)."""
            with lock:
                seq = params[k.H_STAGE_SEQ]
                params[k.H_STAGE_SEQ] = seq + 1.0          # odd: writing
                np.copyto(staged, block)
                params[k.H_STAGE_SEQ] = seq + 2.0          # even: complete
                self._omega, self._p_inj = point

        return swap

    @property
    def operating_point(self) -> tuple[float, float]:
        """(Ω rpm, P_I bar) last set (applied by the kernel at its next step)."""
        return self._omega, self._p_inj

    def impact(self, axis: str, peak_n: float, duration_s: float) -> None:
        """Hit the disc with the impact hammer: a half-sine force pulse on ``axis`` (x or y).

        The pulse starts at the next step and is recorded in ``f_x``/``f_y`` (N). Safe to
        call from another thread.
        """
        if axis not in ("x", "y"):
            raise InputError(f"impact axis must be 'x' or 'y' (got {axis!r})", "impact")
        if not (math.isfinite(peak_n) and abs(peak_n) <= 1000.0):
            raise InputError(f"impact peak must be within ±1000 N (got {peak_n!r})", "impact")
        T = 1.0 / self.fs
        if not (math.isfinite(duration_s) and 2 * T <= duration_s <= 0.1):
            raise InputError(f"impact duration must be in [{2 * T:g}, 0.1] s "
                             f"(got {duration_s!r})", "impact")
        with self._lock:
            self.params[k.H_IMP_AXIS] = 0.0 if axis == "x" else 1.0
            self.params[k.H_IMP_PEAK] = float(peak_n)
            self.params[k.H_IMP_DUR] = float(duration_s)
            self.params[k.H_IMP_SEQ] += 1.0

    def run(self, drives: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
        """Open-loop batch: apply ``drives`` (n, 4) V, return the sensor frames (n, N_IN).

        ``frames[i]`` is the frame after step i (sample i + 1). Convenience for tests and
        offline studies; the loop uses :meth:`write` or the kernel directly.
        """
        drives = np.ascontiguousarray(drives, dtype=float)
        if drives.ndim != 2 or drives.shape[1] != N_OUT:
            raise InputError(f"drives must have shape (n, {N_OUT}) (got {drives.shape})", "run")
        if frames is None:
            frames = np.zeros((drives.shape[0], N_IN))
        k.run_batch(self.state, self.params, drives, frames)
        return frames

    def describe(self) -> dict[str, Any]:
        """The true parameters at the current operating point (for reports and design)."""
        om, pi = self._omega, self._p_inj
        bm = phys.bearing_matrices(om, pi)
        f, z = phys.bearing_modes(om, pi)
        return {
            "omega_rpm": om, "p_inj_bar": pi, "fs": self.fs,
            "modes_hz": f.tolist(), "damping_ratios": z.tolist(),
            "M_kg": bm.M.tolist(), "D_N_s_per_m": bm.D.tolist(), "G_kg": bm.G.tolist(),
            "K_N_per_m": bm.K.tolist(), "B_p_uN_per_V": bm.B_p.tolist(),
            "D_id": bm.D_id.tolist(), "K_id": bm.K_id.tolist(), "B_id": bm.B_id.tolist(),
            "valves": [vars(v) for v in phys.valve_params(self.opts.valves.f_scale)],
            "pd_suggested": {"kp": phys.PD_KP, "kd": phys.PD_KD, "tau_d": phys.PD_TAU_D},
            "effects_enabled": self.opts.effects.enabled(),
            "effects": self.opts.effects.model_dump(),
            "seed": self.opts.seed, "noise": self.opts.noise.model_dump(),
        }
