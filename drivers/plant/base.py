"""What the simulated plant drivers share: options validation, loop-rate check, the staged
operating-point swap, the impact hammer request and the open-loop batch.

:class:`SimulatedPlantDriver` is the base of the ``sim`` (:mod:`rigd_drivers.sim.driver`) and
``sim_reynolds`` (:mod:`rigd_drivers.reynolds.driver`) drivers. Each subclass keeps its own
physics: it builds its ``state``/``params`` arrays and what the base reads of them
(``_frame_view``, the sensor frame; ``_stage_start``, the staged block's index), names its
compiled kernel module (``_kmod``: ``plant_step``, ``plant_sense``, ``run_batch``) and the
module holding its ``params`` header indices (``_hdr``:
``H_STAGE_SEQ``, ``H_IMP_AXIS``, ``H_IMP_PEAK``, ``H_IMP_DUR``, ``H_IMP_SEQ``), and implements
:meth:`_param_block`, :meth:`reset` and :meth:`describe`.
"""

from __future__ import annotations

import math
import threading
from types import ModuleType
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ValidationError

from rigd.driver import FastDriver
from rigd.errors import InputError
from rigd.frame import N_IN, N_OUT
from rigd_drivers.plant import physics as phys
from rigd_drivers.plant.seqlock import stage_block


def _fmt_loc(loc: tuple) -> str:
    return ".".join(str(p) if not isinstance(p, int) else f"[{p}]" for p in loc)


def validate_options(model_cls: type[BaseModel], options: Any, where: str) -> BaseModel:
    """Validate ``options`` (dict, None or an instance) into ``model_cls``.

    Parameters
    ----------
    model_cls : pydantic model class
    options : dict, model_cls instance or None
        None validates ``{}`` (all defaults).
    where : str
        Key prefix of the options in the config (``"plant."``, ``"drivers.fast.options."``).

    Raises
    ------
    InputError
        One line: the first validation error, at ``where`` + its location in the options.
    """
    if isinstance(options, model_cls):
        return options
    try:
        return model_cls.model_validate(options or {})
    except ValidationError as exc:
        err = exc.errors()[0]
        msg = "unknown key" if err["type"] == "extra_forbidden" else err["msg"]
        if "input" in err and not isinstance(err["input"], (dict, list)) \
                and err["type"] != "extra_forbidden":
            msg += f" (got {err['input']!r})"
        raise InputError(msg, f"{where}{_fmt_loc(err['loc'])}") from None


def check_fs(fs: float) -> None:
    """Raise :class:`InputError` unless the loop rate ``fs`` (Hz) is in [100, 100000]."""
    if not (math.isfinite(fs) and 100.0 <= fs <= 100_000.0):
        raise InputError(f"loop rate must be in [100, 100000] Hz (got {fs!r})", "fs")


class SimulatedPlantDriver(FastDriver):
    """Base of the simulated plant drivers (see the module docstring for the subclass duties).

    The constructor validates ``options`` (dict, None or an ``Options`` instance; an error
    is located under ``options_where``) and the loop rate ``fs`` (Hz), then sets ``opts``,
    ``kernel`` (``_kmod.plant_step``), the two locks and the operating point; the subclass
    then makes ``state``/``params`` and the views, and calls :meth:`reset`.
    """

    simulated = True            # its records say source: simulated
    #: key prefix of the options in the config, for error messages
    options_where: ClassVar[str] = ""
    _kmod: ClassVar[ModuleType]     # compiled kernel: plant_step, plant_sense, run_batch
    #: one plant step per loop cycle: the simulated plant's time is the loop's (rigd.driver)
    plant_clock = "cycle"
    _hdr: ClassVar[ModuleType]      # params header indices H_STAGE_SEQ, H_IMP_*

    state: np.ndarray
    params: np.ndarray
    _frame_view: np.ndarray
    _stage_start: int               # index of the staged block in params

    def __init__(self, options: Any = None, fs: float = 5000.0):
        opts = validate_options(self.Options, options, self.options_where)
        check_fs(fs)
        super().__init__(opts.model_dump(), fs=fs)
        self.opts = opts
        self.kernel = self._kmod.plant_step
        self._lock = threading.Lock()           # impact hammer requests
        self._stage_lock = threading.Lock()     # staged parameter block writers
        self._omega = opts.omega_rpm
        self._p_inj = opts.p_inj_bar
        self._out = np.zeros(N_IN)

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
    def _param_block(self, omega_rpm: float, p_inj_bar: float) -> np.ndarray:
        """The parameter block of (Ω rpm, P_I bar) (subclass: its own physics)."""
        raise NotImplementedError

    def set_operating_point(self, omega_rpm: float, p_inj_bar: float) -> None:
        """Change Ω (rpm) and P_I (bar); safe to call from another thread while the loop runs.

        The new parameter set is staged and swapped in whole by the kernel at the start of
        its next step (sequence lock: never a torn set). The plant's states (shaft, valves,
        film) carry on from where they are.

        Raises
        ------
        InputError
            Operating point outside Ω ∈ [0, 6000] rpm, P_I ∈ [3, 7] bar.
        """
        self.prepare_operating_point(omega_rpm, p_inj_bar)()

    def prepare_operating_point(self, omega_rpm: float, p_inj_bar: float):
        """Build the parameter block of (Ω rpm, P_I bar) now; return its O(1) swap.

        Runs in: the caller's thread (matrix exponentials and allocations: never the loop
        thread). The returned callable stages the prepared block under the sequence lock
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
        block = self._param_block(float(omega_rpm), float(p_inj_bar))
        point = (float(omega_rpm), float(p_inj_bar))
        params, start, lock = self.params, self._stage_start, self._stage_lock
        i_seq = self._hdr.H_STAGE_SEQ

        def swap() -> None:
            """Stage the prepared block. Runs in: loop thread — O(1), no allocation, no wait
            (the stage lock has no other holder while a loop owns the driver)."""
            with lock:
                stage_block(params, i_seq, start, block)   # sequence word odd while copying
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
        h = self._hdr
        with self._lock:
            self.params[h.H_IMP_AXIS] = 0.0 if axis == "x" else 1.0
            self.params[h.H_IMP_PEAK] = float(peak_n)
            self.params[h.H_IMP_DUR] = float(duration_s)
            self.params[h.H_IMP_SEQ] += 1.0

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
        self._kmod.run_batch(self.state, self.params, drives, frames)
        return frames
