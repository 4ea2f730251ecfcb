"""``ControlLoop``: the cycle on a clock, with thread-safe commands (docs/ARCHITECTURE.md).

One ``ControlLoop`` per process. The same compiled cycle (:mod:`rigd.loop.cycle`) runs on:

* the **real-time clock** (``start()``): a loop thread calls the fast driver's ``read``, the
  cycle kernel and ``write`` once per period (see :mod:`rigd.loop.clock`);
* the **lock-step clock** (``run_cycles`` / ``run_segment`` in the caller's thread): batches of
  cycles inside one compiled call together with the simulated plant's ``plant_step`` kernel,
  as fast as the CPU allows.

Commands (``enable_controller``, ``load_controller``, ``reset_fault``, ``set_operating_point``)
may come from any thread: they are queued and applied by the thread running the cycles at a
cycle (real-time) or batch (lock-step) boundary; they never block the cycle.
"""

from __future__ import annotations

import collections
import queue
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from rigd import frame as F
from rigd.errors import InputError
from rigd.log import get_logger
from rigd.loop import cycle as K
from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop.recorder import Recorder
from rigd.loop.run import LoopRunner, SegmentResult  # noqa: F401 (re-exported)
from rigd.loop.timing import summary
from rigd.rigconfig import LoadedConfig, RigConfig, default_config


class ControlLoop(LoopRunner):
    """The 5 kHz control loop (see module docstring).

    Parameters
    ----------
    config : LoadedConfig or RigConfig
        The rig configuration (``rigd.rigconfig.load_config``).
    fast_driver : rigd.driver.FastDriver
        Per-cycle I/O. A driver with ``kernel``/``state``/``params`` (the simulated plant) runs
        lock-step inside the compiled batch.
    slow_drivers : sequence of rigd.driver.SlowDriver
        Polled in their own threads at ``poll_hz``.
    controller : rigd.controller.Controller or path, optional
        K∞(z) loaded at start (disabled until ``enable_controller(True)``).
    clock : {"realtime", "lockstep"}, optional
        Overrides ``config.clock.mode``.
    """

    def __init__(self, config: LoadedConfig | RigConfig | None, fast_driver, *,
                 slow_drivers: Sequence = (), slow_poll_hz: Sequence[float] = (),
                 controller=None, clock: str | None = None) -> None:
        if config is None:
            config = default_config()
        if isinstance(config, RigConfig):
            config = LoadedConfig(config, "<memory>", "")
        self.loaded = config
        self.config = cfg = config.config
        self.fs = cfg.loop.fs_hz
        self.clock = clock or cfg.clock.mode
        if self.clock not in ("realtime", "lockstep"):
            raise InputError(f"unknown clock {self.clock!r} (realtime or lockstep)")
        self.fast = fast_driver
        self.slow = list(slow_drivers)
        self._slow_hz = list(slow_poll_hz) or [getattr(d, "poll_hz", 20.0) for d in self.slow]
        self.log = get_logger("rigd.loop")
        self.prm = np.zeros(L.N_PRM)
        self.st = np.zeros(L.N_ST)
        self.fin = np.zeros(F.N_IN)
        self.drive = np.zeros(F.N_OUT)
        self.hist = K.hist_new()
        self._fill_params()
        self.recorder = Recorder(cfg.recorder.ring_frames, self.st,
                                 flush_interval_s=cfg.recorder.flush_interval_s,
                                 on_error=self._recorder_failed)
        self.prm[L.P_RING_N] = cfg.recorder.ring_frames
        self._cmds: collections.deque = collections.deque()
        self._subscribers: list[queue.Queue] = []
        self._fault_history: list[dict] = []
        self._seen_faults = 0
        self._fault_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._monitor: threading.Thread | None = None
        self._slow_threads: list[threading.Thread] = []
        self._slow_last_ok: list[float] = []
        self._seg = None  # the segment being played (rigd.loop.run._Segment) or None
        self._pending_ctrl = None
        self.controller = None
        self._opened = False
        self._driver_error: BaseException | None = None
        self.overruns = 0
        self.skipped = 0
        self.rt_warnings: list[str] = []
        self._lock_cycles = 0
        self._lock_wall = 0.0
        self._lock = threading.Lock()          # one runner at a time (lock-step)
        self._pk = getattr(fast_driver, "kernel", None)
        if controller is not None:
            self._set_controller(self._as_controller(controller))

    # --- set-up -------------------------------------------------------------------------
    def _fill_params(self) -> None:
        c = self.config
        p, T = self.prm, 1.0 / self.fs
        p[L.P_FS] = self.fs
        p[L.P_R0] = c.loop.r0_v
        p[L.P_VMIN], p[L.P_VMAX] = c.loop.drive_v
        p[L.P_RAMP_STEP] = 1.0 if c.loop.k_ramp_s == 0 else T / c.loop.k_ramp_s
        p[L.P_PEQ_ALPHA] = 1.0 - np.exp(-T / c.loop.peq_tau_s)
        for i, v in enumerate(c.valves):
            p[L.P_KP + i], p[L.P_KD + i], p[L.P_KFF + i] = v.kp, v.kd, v.kff
            p[L.P_DA + i] = v.tf_s / (v.tf_s + T)
            p[L.P_DB + i] = 1.0 / (v.tf_s + T)
        g, o = c.calibration_arrays()
        p[L.P_CAL_G:L.P_CAL_G + F.N_IN] = g
        p[L.P_CAL_O:L.P_CAL_O + F.N_IN] = o
        s = c.supervisor
        p[L.P_SUP_ON] = 1.0 if s.enabled else 0.0
        p[L.P_E_MIN], p[L.P_E_MAX] = s.e_range_um
        p[L.P_Y_MIN], p[L.P_Y_MAX] = s.y_p_range_v
        p[L.P_GAP_MAX] = s.max_gap_fraction * s.film_gap_um
        p[L.P_CX], p[L.P_CY] = s.centre_um
        p[L.P_STALE_N] = s.stale_frames
        p[L.P_ENC_OMEGA] = s.encoder_min_omega_rpm
        p[L.P_ENC_N] = round(s.encoder_frozen_s * self.fs)
        p[L.P_VERR_V] = s.valve_error_v
        p[L.P_VERR_N] = round(s.valve_error_s * self.fs)
        st = self.st
        st[L.S_EPREV:L.S_EPREV + 4] = np.nan
        st[L.S_RP_PREV:L.S_RP_PREV + 4] = c.loop.r0_v
        st[L.S_LAST_DRVSEQ] = np.nan
        st[L.S_SLOW_OMEGA] = st[L.S_SLOW_PINJ] = np.nan
        st[L.S_FAULT_DETAIL] = -1

    def _as_controller(self, controller):
        from rigd.controller import Controller, load_controller

        if isinstance(controller, Controller):
            if abs(controller.fs_hz - self.fs) > 1e-9 * self.fs:
                raise InputError(f"controller rate {controller.fs_hz:g} Hz differs from the loop "
                                 f"rate {self.fs:g} Hz", controller.source)
            return controller
        return load_controller(controller, expected_fs_hz=self.fs)

    def _set_controller(self, ctrl) -> None:
        """Write K∞ matrices into prm and zero its state (between cycles only)."""
        p = self.prm
        if ctrl is None:
            p[L.P_KN] = 0
            p[L.P_KD_MAT:L.P_KD_MAT + 4] = 0.0
        else:
            n = ctrl.order
            if n > L.K_NMAX:
                raise InputError(f"controller order {n} exceeds {L.K_NMAX}", ctrl.source)
            p[L.P_KN] = n
            p[L.P_KA:L.P_KA + n * n] = np.asarray(ctrl.A, float).ravel()
            p[L.P_KB:L.P_KB + 2 * n] = np.asarray(ctrl.B, float).ravel()
            p[L.P_KC:L.P_KC + 2 * n] = np.asarray(ctrl.C, float).ravel()
            p[L.P_KD_MAT:L.P_KD_MAT + 4] = np.asarray(ctrl.D, float).ravel()
        self.st[L.S_X:L.S_X + L.K_NMAX] = 0.0
        self.controller = ctrl

    def open(self) -> ControlLoop:
        """Open drivers, start the recorder, monitor and slow-driver threads."""
        if self._opened:
            return self
        self.fast.open()
        for d in self.slow:
            d.open()
        self.fast.read(self.fin)
        self._warm_up()
        self.recorder.start()
        self._opened = True
        self._monitor = threading.Thread(target=self._monitor_run, name="rigd-monitor",
                                         daemon=True)
        self._monitor.start()
        now = time.monotonic()
        for i, d in enumerate(self.slow):
            self._slow_last_ok.append(now)
            t = threading.Thread(target=self._slow_run, args=(i, d), name=f"rigd-slow-{i}",
                                 daemon=True)
            t.start()
            self._slow_threads.append(t)
        return self

    def _warm_up(self) -> None:
        """Load (or compile) the kernels now, on scratch copies: the first real cycle is fast."""
        ring = np.zeros((4, F.N_REC))
        prm = self.prm.copy()
        prm[L.P_RING_N] = 4
        K.rt_cycle(self.fin.copy(), prm, self.st.copy(), self.drive.copy(), ring,
                   np.zeros((1, 2)), -1, K.hist_new(), 0, -1)
        K.cycle(self.fin.copy(), prm, self.st.copy(), self.drive.copy(), ring, 0.0, 0.0)
        f = self.fast
        if self._pk is not None and hasattr(f, "state") and hasattr(f, "params"):
            # the plant's kernel too (driver.write calls it on the real-time path): a compile
            # must never happen inside the loop thread
            self._pk(f.state.copy(), f.params.copy(), self.drive.copy(), self.fin.copy())

    def __enter__(self) -> ControlLoop:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    # --- commands (any thread) -------------------------------------------------------
    def enable_controller(self, on: bool = True) -> None:
        """Blend K∞ in (on) or out over ``loop.k_ramp_s``; p_eq is frozen while on."""
        self._cmds.append(("enable", bool(on)))

    def load_controller(self, path_or_controller) -> None:
        """Validate a controller file now (raises InputError), switch to it bumplessly."""
        ctrl = self._as_controller(path_or_controller)
        self._cmds.append(("controller", ctrl))

    def reset_fault(self) -> None:
        """Clear the latched fault (it latches again next cycle if the cause persists)."""
        self._cmds.append(("reset", None))

    def trip(self, code: int = FC.OPERATOR_STOP) -> None:
        """Put the loop into the safe state with ``code`` latched (operator / service)."""
        self.st[L.S_EXT_FAULT] = code

    def set_operating_point(self, omega_rpm: float, p_inj_bar: float) -> None:
        """Sim: plant operating point (at a cycle boundary); rig: slow-driver setpoints."""
        from rigd.rigconfig import OperatingPoint

        OperatingPoint(omega_rpm=omega_rpm, p_inj_bar=p_inj_bar)   # range check
        if hasattr(self.fast, "set_operating_point"):
            self._cmds.append(("op", (float(omega_rpm), float(p_inj_bar))))
        else:
            for d in self.slow:
                threading.Thread(target=self._slow_setpoint, args=(d, omega_rpm, p_inj_bar),
                                 daemon=True).start()

    def _slow_setpoint(self, d, omega, p) -> None:
        try:
            d.write_setpoints(omega_rpm=omega, p_inj_bar=p)
        except NotImplementedError:
            pass
        except Exception as exc:
            self.log.error("slow driver setpoint failed", driver=d.name, error=str(exc))

    def stop(self) -> None:
        """Ask the running loop to stop (returns at once; ``close()`` waits and cleans up)."""
        self._stop.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def subscribe(self) -> queue.Queue:
        """A queue that receives one dict per latched fault: seq, code, name, text, time."""
        q: queue.Queue = queue.Queue()
        self._subscribers.append(q)
        return q

    def _apply_commands(self) -> None:
        st = self.st
        while self._cmds:
            kind, arg = self._cmds.popleft()
            if kind == "enable":
                if self._pending_ctrl is not None:
                    self._pending_ctrl = (self._pending_ctrl[0], arg)
                else:
                    st[L.S_K_TARGET] = 1.0 if arg else 0.0
            elif kind == "controller":
                if st[L.S_RAMP] == 0.0 and st[L.S_K_TARGET] == 0.0:
                    self._set_controller(arg)
                else:  # blend out, swap, blend back in (see _check_pending)
                    self._pending_ctrl = (arg, st[L.S_K_TARGET] != 0.0)
                    st[L.S_K_TARGET] = 0.0
            elif kind == "reset":
                st[L.S_FAULT] = 0.0
                st[L.S_FAULT_DETAIL] = -1.0
                st[L.S_STALE_CNT] = st[L.S_PHI_CNT] = 0.0
                st[L.S_VERR_CNT:L.S_VERR_CNT + 4] = 0.0
                st[L.S_K_TARGET] = 0.0          # K∞ stays off after a fault until re-enabled
            elif kind == "op":
                self.fast.set_operating_point(*arg)
        if self._pending_ctrl is not None and st[L.S_RAMP] == 0.0:
            ctrl, back_on = self._pending_ctrl
            self._pending_ctrl = None
            self._set_controller(ctrl)
            st[L.S_K_TARGET] = 1.0 if back_on else 0.0

    # --- queries (any thread) ---------------------------------------------------------
    def status(self) -> dict[str, Any]:
        st = self.st
        w = int(st[L.S_W])
        last = self.recorder.ring[(w - 1) % self.recorder.n] if w else np.full(F.N_REC, np.nan)
        code = int(st[L.S_FAULT])
        return {
            "running": self.running,
            "clock": self.clock,
            "fs_hz": self.fs,
            "seq": int(st[L.S_SEQ]),
            "t_s": st[L.S_SEQ] / self.fs,
            "fault": {"code": code, "name": FC.fault_name(code),
                      "text": FC.describe(code, int(st[L.S_FAULT_DETAIL])) if code else "",
                      "seq": int(st[L.S_FAULT_SEQ]) if code else None},
            "controller": {"loaded": self.controller is not None,
                           "source": getattr(self.controller, "source", None),
                           "order": int(self.prm[L.P_KN]),
                           # enabled: K∞ really in the loop (what the recording's k_on says);
                           # requested: the operator's enable, overridden while a fault is
                           # latched and cleared by fault.reset
                           "enabled": bool(st[L.S_K_TARGET]) and code == 0,
                           "requested": bool(st[L.S_K_TARGET]),
                           "blend": float(st[L.S_RAMP]),
                           "p_eq_um": [float(st[L.S_PEQ_X]), float(st[L.S_PEQ_Y])]},
            "last_frame": {n: float(last[F.REC[n]]) for n in
                           ("e_x", "e_y", "u_x", "u_y", "r_x", "r_y", "omega_rpm", "p_inj_bar")},
            "recorder": {"written": w, "consumed": int(st[L.S_RD]),
                         "dropped": int(st[L.S_DROPPED]), "ring_frames": self.recorder.n},
            "overruns": self.overruns,
            "drivers": {"fast": {"name": getattr(self.fast, "name", "?"),
                                 **self.fast.counters()},
                        "slow": [{"name": d.name, **d.counters()} for d in self.slow]},
        }

    def timing(self) -> dict[str, Any]:
        """Timing statistics: real-time percentiles (µs) and overruns, or lock-step speed."""
        if self.clock == "lockstep":
            wall = self._lock_wall
            n = self._lock_cycles
            return {"clock": "lockstep", "cycles": n, "wall_s": wall,
                    "cycles_per_s": n / wall if wall > 0 else 0.0,
                    "realtime_factor": n / wall / self.fs if wall > 0 else 0.0}
        return summary(self.hist, overruns=self.overruns, skipped=self.skipped,
                       cycles=int(self.hist[L.H_LATE, L.H_COUNT]))

    def faults(self) -> list[dict]:
        """Every fault latched since start (oldest first) plus the current latched code."""
        self._poll_faults()
        return list(self._fault_history)

    @property
    def running(self) -> bool:
        return (self._thread is not None and self._thread.is_alive()) or self._lock.locked()

    # --- faults ------------------------------------------------------------------------
    def _recorder_failed(self, exc: BaseException) -> None:
        self.st[L.S_EXT_FAULT] = FC.RECORDER_OVERFLOW
        self.log.error("recording failed", error=str(exc))

    def _poll_faults(self) -> None:
        with self._fault_lock:      # monitor thread, runners and faults() may all call this
            self._poll_faults_locked()

    def _poll_faults_locked(self) -> None:
        st = self.st
        n = int(st[L.S_NFAULT])
        while self._seen_faults < n:
            k = self._seen_faults % L.FLOG_N
            seq, code, detail = st[L.S_FLOG + 3 * k:L.S_FLOG + 3 * k + 3]
            self._seen_faults += 1
            ev = {"seq": int(seq), "code": int(code), "name": FC.fault_name(code),
                  "text": FC.describe(code, int(detail)), "time": time.time()}
            if code == FC.DRIVER_EXCEPTION and self._driver_error is not None:
                ev["text"] += f": {self._driver_error!r}"
            self._fault_history.append(ev)
            self.recorder.add_event(ev["seq"], ev["code"], f"fault {ev['name']}: {ev['text']}")
            self.log.error("fault latched", **{k2: v for k2, v in ev.items() if k2 != "time"})
            for q in self._subscribers:
                q.put(ev)

    def _monitor_run(self) -> None:
        stale = self.config.supervisor.slow_stale_s
        while not self._stop.wait(0.02):
            self._poll_faults()
            now = time.monotonic()
            for i, t in enumerate(self._slow_last_ok):
                if now - t > stale and self.st[L.S_FAULT] == 0.0:
                    self.st[L.S_EXT_FAULT] = FC.SLOW_DRIVER
                    self._slow_last_ok[i] = now
        self._poll_faults()

    def _slow_run(self, i: int, d) -> None:
        period = 1.0 / self._slow_hz[i]
        failed = False
        while not self._stop.wait(period):
            try:
                vals = d.poll()
            except Exception as exc:
                if not failed:
                    self.log.error("slow driver failed", driver=d.name, error=str(exc))
                    self.st[L.S_EXT_FAULT] = FC.SLOW_DRIVER
                failed = True
                continue
            failed = False
            self._slow_last_ok[i] = time.monotonic()
            if "omega_rpm" in vals:
                self.st[L.S_SLOW_OMEGA] = float(vals["omega_rpm"])
            if "p_inj_bar" in vals:
                self.st[L.S_SLOW_PINJ] = float(vals["p_inj_bar"])
