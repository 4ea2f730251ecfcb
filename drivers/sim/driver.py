"""The simulated rotor-gas bearing rig: a :class:`rigd.driver.FastDriver` (entry point ``sim``).

Four piezo valves (drive voltage → position, second order, optional hysteresis and creep), the
lumped 2-DOF bearing of Eq. 4 with M, D, G, K, B_p depending on the operating point
(Ω, P_I) (see :mod:`rigd_drivers.plant.physics`), encoder angle, optional run-out and mass
unbalance, sensor noise, an impact hammer, and hidden effects switched on in ``plant.effects``.

The compiled kernel (:func:`rigd_drivers.sim.kernel.plant_step`) is exposed as
``driver.kernel`` with its arrays ``driver.state`` and ``driver.params`` so that the lock-step
runner can call it from its own compiled loop; :meth:`read`/:meth:`write` use the same kernel.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.frame import N_IN
from rigd_drivers.plant import physics as phys
from rigd_drivers.plant.base import SimulatedPlantDriver
from rigd_drivers.sim import kernel as k
from rigd_drivers.sim.options import PlantOptions
from rigd_drivers.sim.params import ParamBlocks, rest_state


class SimPlantDriver(SimulatedPlantDriver):
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
    options_where = "plant."
    _kmod = k
    _hdr = k

    def __init__(self, options: dict[str, Any] | PlantOptions | None = None,
                 fs: float = 5000.0):
        super().__init__(options, fs)
        self.params = np.zeros(k.N_PARAMS)
        self.state = np.zeros(k.N_STATE)
        self._frame_view = self.state[k.S_FRAME:k.S_FRAME + N_IN]
        self._stage_start = k.STG
        self._blocks = ParamBlocks(self.opts, self.fs)
        self.reset()

    def plant_time_constant_s(self) -> float:
        """The fastest envelope time constant 1 / (ζ ω_n) of the bearing modes over the whole
        operating range (Ω 0–6000 rpm, P_I 3–7 bar; K∞ off: the plant as the loop holds it),
        s — 18.1 ms for the paper's plant (3 bar, 6000 rpm, the second mode)."""
        best = np.inf
        for p_inj in np.linspace(3.0, 7.0, 9):
            for omega in np.linspace(0.0, 6000.0, 7):
                f, z = phys.bearing_modes(float(omega), float(p_inj))
                best = min(best, float(np.min(1.0 / (z * 2.0 * np.pi * f))))
        return best

    # --- plant control ------------------------------------------------------------------
    def reset(self, drive_v: float | None = None) -> None:
        """Put the plant at rest under a constant drive (default ``valves.initial_drive_v``).

        Not thread-safe with a running loop: call before the loop starts. Time, angle and the
        noise stream restart from zero.
        """
        v0 = self.opts.valves.initial_drive_v if drive_v is None else float(drive_v)
        block = self._blocks(self._omega, self._p_inj)
        self.params[:] = 0.0
        self.params[k.ACT:k.ACT + k.NA] = block
        self.params[k.STG:k.STG + k.NA] = block
        self.state[:] = rest_state(self.opts, block, self._omega, self._p_inj, v0)
        k.plant_sense(self.state, self.params, self._out)

    def _param_block(self, omega_rpm: float, p_inj_bar: float) -> np.ndarray:
        """The lumped parameter block of (Ω rpm, P_I bar) (one compiled call without the GIL:
        two matrix exponentials and their glue)."""
        return self._blocks(omega_rpm, p_inj_bar)

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
