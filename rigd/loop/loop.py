"""``ControlLoop``: the cycle on a clock, composed of parts with one owner each (docs/loop.md).

One ``ControlLoop`` per process. It owns and wires together:

* :class:`~rigd.loop.state.KernelState` — the preallocated arrays of the compiled cycle;
* :class:`~rigd.loop.requests.FaultRequests` — the single-writer fault request slots;
* :class:`~rigd.loop.commands.CommandQueue` — commands from any thread, applied at a boundary;
* :class:`~rigd.loop.recorder.Recorder` — ring buffer, keeper thread, writer process link;
* :class:`~rigd.loop.supervisor.Supervisor` — fault events, monitor thread, loop death;
* :class:`~rigd.loop.slow.SlowPollers` — slow-driver threads;
* :class:`~rigd.loop.segment.SegmentPlayer` — the excitation segment being played;
* the clock: :class:`~rigd.loop.realtime.RealTimeClock` (``start()``: a loop thread, one cycle
  per period) or :class:`~rigd.loop.lockstep.LockstepClock` (``run_cycles``/``run_segment`` in
  the caller's thread, batches as fast as the CPU allows).

Commands (``enable_controller``, ``load_controller``, ``reset_fault``, ``set_operating_point``,
``trip``) may come from any thread: they validate and prepare in the caller's thread and post
an O(1) step that the thread running the cycles applies at a cycle (real-time) or batch
(lock-step) boundary; they never block the cycle. Methods that run in the loop thread say so
in their docstrings ("Runs in: loop thread — O(1), allocation-free, non-blocking").
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rigd import frame as F
from rigd.errors import InputError
from rigd.log import get_logger
from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop import requests as RQ
from rigd.loop.clock import boosted
from rigd.loop.commands import DROP_LATE, DROP_SAFE, CommandDropped, CommandQueue, Ticket
from rigd.loop.cycle import cycle, hist_new, rt_cycle
from rigd.loop.liveness import derive as derive_liveness
from rigd.loop.liveness import fill as fill_liveness
from rigd.loop.lockstep import LockstepClock
from rigd.loop.realtime import RealTimeClock
from rigd.loop.recorder import Recorder
from rigd.loop.safeword import W_ACK_CODE, W_ACK_FAULT_SEQ, W_STALL_BOUND_NS, SafeWord
from rigd.loop.segment import Segment, SegmentPlayer, SegmentResult, segment_inputs
from rigd.loop.setpoint import SetPoint
from rigd.loop.sinks import FileSink, MemorySink, RecordSpec, Sink, make_sink
from rigd.loop.slow import SlowPollers
from rigd.loop.state import KernelState, PackedController
from rigd.loop.supervisor import Supervisor
from rigd.loop.timing import summary
from rigd.rigconfig import LoadedConfig, RigConfig, default_config

__all__ = ["ControlLoop", "SegmentResult"]


class ControlLoop:
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
        self.log = get_logger("rigd.loop")
        self.fast = fast_driver
        self.slow = list(slow_drivers)
        self._stop = threading.Event()
        self._opened = False
        # the parts, each the one owner of what it holds
        self.state = KernelState(cfg, cfg.recorder.ring_frames)
        self.requests = RQ.FaultRequests(self.state.st)
        self.commands = CommandQueue(self.state)
        #: the SAFE request word the cycle reads every cycle (rigd.loop.safeword)
        self.safe = SafeWord()
        self.player = SegmentPlayer()
        self.recorder = Recorder(cfg.recorder.ring_frames, self.state.st,
                                 flush_interval_s=cfg.recorder.flush_interval_s,
                                 on_error=self._recorder_failed, fs=self.fs)
        self.recorder.helper_priority = lambda: self.rt.helper_priority
        if self.clock == "lockstep":     # frames written beyond the published count, at most
            self.recorder.shared.set_ahead(cfg.clock.batch_cycles)
        self.supervisor = Supervisor(self.state, self.requests, self.recorder, self.log,
                                     cfg.supervisor.slow_stale_s)
        self.slow_pollers = SlowPollers(self.slow, slow_poll_hz, self.state.st, self.requests,
                                        self.log,
                                        first_poll_s=cfg.supervisor.slow_first_poll_s)
        self.supervisor.slow = self.slow_pollers
        self.supervisor.fast = self.fast
        self.supervisor.safe = self.safe
        #: stall and overrun-storm bounds derived from the plant (rigd.loop.liveness)
        self.liveness = derive_liveness(cfg.supervisor, fast_driver)
        fill_liveness(self.state.prm, self.liveness, self.fs)
        if self.clock == "realtime":       # the watchdog and the status read it (0: no watch)
            self.safe.word[W_STALL_BOUND_NS] = int(self.liveness.stall_s * 1e9)
        self.rt = RealTimeClock(cfg, self)
        self.lockstep = LockstepClock(cfg, self)
        #: what ``set_operating_point`` last applied (``status()["set_point"]``); a simulated
        #: plant starts at its configured operating point
        op0 = getattr(fast_driver, "operating_point", None)
        self.set_point = SetPoint(tuple(op0) if op0 is not None else None)
        if controller is not None:
            self.state.swap_controller(PackedController(self._as_controller(controller)))

    # --- set-up -------------------------------------------------------------------------
    def _as_controller(self, controller):
        """A controller checked for this loop (any thread; see ``rigd.controller.for_loop``)."""
        from rigd.controller import for_loop

        return for_loop(controller, self.fs)

    @property
    def controller(self):
        """The controller in the loop (None: zero output)."""
        return self.state.controller

    def open(self) -> ControlLoop:
        """Configure and activate the drivers, start the recorder, monitor and slow threads."""
        if self._opened:
            return self
        self.fast.configure()
        for d in self.slow:
            d.configure()
        self.fast.read(self.state.fin)
        self._warm_up()
        self.fast.activate()
        for d in self.slow:
            d.activate()
        self.recorder.start()
        self._opened = True
        self.supervisor.start(self._stop)
        self.slow_pollers.start(self._stop)
        return self

    def _warm_up(self) -> None:
        """Load (or compile) the kernels now, on scratch copies: the first real cycle is fast."""
        s = self.state
        ring = np.zeros((4, F.N_REC))
        prm = s.prm.copy()
        prm[L.P_RING_N] = 4
        rt_cycle(s.fin.copy(), prm, s.st.copy(), s.drive.copy(), ring, np.zeros((1, 2)), -1,
                 hist_new(), 0, -1, self.safe.word.copy(), 0)
        cycle(s.fin.copy(), prm, s.st.copy(), s.drive.copy(), ring, 0.0, 0.0)
        self.lockstep.warm_up()
        f, pk = self.fast, getattr(self.fast, "kernel", None)
        if pk is not None and hasattr(f, "state") and hasattr(f, "params"):
            # the plant's kernel too (driver.write calls it on the real-time path): a compile
            # must never happen inside the loop thread
            pk(f.state.copy(), f.params.copy(), s.drive.copy(), s.fin.copy())

    def __enter__(self) -> ControlLoop:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    # --- commands (any thread) -------------------------------------------------------
    # Each command returns its ticket: ``wait_applied(ticket)`` waits until the loop has
    # applied it (the daemon does, so that ``status`` after the reply shows the change).
    # ``gen`` (the SAFE generation the command was sent in, :attr:`safe_generation`; default
    # now) and ``deadline`` (``time.monotonic()``; default none) make the loop drop it rather
    # than apply it after a SAFE or too late (rigd.loop.commands: applied when answered, or
    # never).
    def enable_controller(self, on: bool = True, *, gen: int | None = None,
                          deadline: float | None = None) -> Ticket:
        """Blend K∞ in (on) or out over ``loop.k_ramp_s``; p_eq is frozen while on. An enable
        is dropped (:data:`~rigd.loop.commands.DROP_FAULT`) while a fault is latched."""
        return self.commands.enable(on, gen, deadline)

    def load_controller(self, path_or_controller, *, gen: int | None = None,
                        deadline: float | None = None) -> Ticket:
        """Validate a controller now (raises InputError), switch to it bumplessly (once K∞
        has blended out, if it is in)."""
        return self.commands.controller(
            PackedController(self._as_controller(path_or_controller)), gen, deadline)

    def reset_fault(self, *, gen: int | None = None, deadline: float | None = None) -> Ticket:
        """Clear the latched fault (it latches again next cycle if the cause persists)."""
        return self.commands.reset(gen, deadline)

    def applied(self, ticket: Ticket) -> bool:
        """Has the loop applied the command that returned ``ticket``?"""
        return self.commands.applied(ticket)

    def wait_applied(self, ticket: Ticket | None, timeout_s: float | None = None, *,
                     cancel: bool = False) -> bool:
        """Wait until the loop has applied (or dropped) the command that returned ``ticket``.

        Parameters
        ----------
        ticket : rigd.loop.commands.Ticket or None
            From ``enable_controller``, ``load_controller``, ``reset_fault`` or
            ``set_operating_point`` (None: nothing to wait for, True at once).
        timeout_s : float, optional
            Bound on the wait, s; default 2 s plus two blend times (a controller swap waits
            for K∞ to blend out).
        cancel : bool
            When the bound passes with the command still queued, cancel it: the loop will
            then never apply it (``ticket.dropped`` says so).

        Returns
        -------
        bool
            True once applied; False when dropped (``ticket.dropped`` says why), at once when
            no cycles are being run (the command stays queued for the next run), or when the
            bound passed.
        """
        if ticket is None or ticket.applied:
            return True
        if timeout_s is None:
            timeout_s = 2.0 + 2.0 * self.config.loop.k_ramp_s
        end = time.monotonic() + timeout_s
        while self.running:
            if ticket.done:
                return ticket.applied
            if time.monotonic() > end:
                break
            time.sleep(0.001)
        if cancel and not ticket.done and self.running and not ticket.cancel():
            end = time.monotonic() + 1.0          # the loop took it this instant
            while not ticket.done and time.monotonic() < end:
                time.sleep(0.0005)
        return ticket.applied

    def trip(self, code: int = FC.OPERATOR_STOP) -> None:
        """Put the loop into the safe state with ``code`` latched (operator / service)."""
        if int(code) == FC.OPERATOR_SAFE:
            self.request_safe()
            return
        self.requests.post(RQ.OPERATOR, int(code))

    def request_safe(self) -> int:
        """SAFE through the shared word (:mod:`rigd.loop.safeword`): ``operator_safe`` latches
        in the next cycle whatever else is queued. Returns ``c0`` for :meth:`wait_safe`.

        Runs in: any thread (a signal handler too) — two stores, no lock, no allocation
        beyond the request value.
        """
        return self.safe.request()

    def wait_safe(self, c0: int, timeout_s: float = 2.0) -> dict[str, Any] | None:
        """Wait until the loop has taken a SAFE request at a cycle ``>= c0``.

        Returns
        -------
        dict or None
            ``{"requested_at": c0, "latched_at": cycle it was taken, "fault": {code, name,
            text, seq}}`` (the fault in force: ``operator_safe`` or an earlier one); None when
            no cycle took it within ``timeout_s`` (the loop is not running cycles; the
            request stays pending for the next cycle).
        """
        end = time.monotonic() + timeout_s
        while True:
            at = self.safe.acknowledged_at()
            if at >= c0:
                w = self.safe.word
                code = int(w[W_ACK_CODE])
                return {"requested_at": int(c0), "latched_at": at,
                        "fault": {"code": code, "name": FC.fault_name(code),
                                  "text": FC.fault_text(code), "seq": int(w[W_ACK_FAULT_SEQ])}}
            if time.monotonic() > end:
                return None
            time.sleep(0.0005)

    @property
    def safe_generation(self) -> int:
        """SAFE requests the cycle has taken so far (a command posted before it is dropped)."""
        return int(self.state.st[L.S_SAFE_GEN])

    def set_operating_point(self, omega_rpm: float, p_inj_bar: float, *,
                            gen: int | None = None, deadline: float | None = None
                            ) -> Ticket | None:
        """Sim: plant operating point (at a cycle boundary); rig: slow-driver setpoints.

        The slow preparation (the plant's parameter block) runs here, in the caller's thread;
        the loop thread only swaps the prepared block in (O(1)). Returns the swap's ticket
        (None when nothing is queued to the loop).
        """
        from rigd.rigconfig import OperatingPoint

        OperatingPoint(omega_rpm=omega_rpm, p_inj_bar=p_inj_bar)   # range check
        om, pi = float(omega_rpm), float(p_inj_bar)
        prepare = getattr(self.fast, "prepare_operating_point", None)
        swap = None
        if prepare is not None:
            # just below the loop thread while it runs real-time: never preempted holding GIL
            with boosted(self.rt.helper_priority if self.rt.alive else None):
                swap = prepare(om, pi)
        if swap is not None:
            ticket = self.commands.call(swap, gen, deadline)
            self.set_point.queued(ticket, om, pi)
            return ticket
        if gen is not None and gen != self.safe_generation:
            raise CommandDropped(f"operating_point.set: {DROP_SAFE}")
        if deadline is not None and time.monotonic() > deadline:
            raise CommandDropped(f"operating_point.set: {DROP_LATE}")
        if hasattr(self.fast, "set_operating_point"):
            self.fast.set_operating_point(om, pi)    # its own thread-safe staging, here
        else:
            self.slow_pollers.set_points(om, pi)
        self.set_point.applied(om, pi)
        return None

    def stop(self) -> None:
        """Ask the running loop to stop (returns at once; ``close()`` waits and cleans up)."""
        self._stop.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def subscribe(self):
        """A queue that receives one dict per latched fault: seq, code, name, text, time."""
        return self.supervisor.subscribe()

    # --- queries (any thread) ---------------------------------------------------------
    @property
    def running(self) -> bool:
        """Cycles are being run (a loop thread, or a lock-step runner) and the loop lives."""
        return self.loop_error is None and (self.rt.alive or self.lockstep.alive or
                                            self.lockstep.lock.locked())

    @property
    def loop_error(self) -> BaseException | None:
        """What killed the loop (the ``loop_died`` fault), None while it is healthy."""
        return self.supervisor.loop_error

    @property
    def overruns(self) -> int:
        return self.rt.overruns

    @property
    def rt_warnings(self) -> list[str]:
        return self.rt.rt_warnings

    def status(self) -> dict[str, Any]:
        s = self.state
        st = s.st
        w = int(st[L.S_W])
        last = self.recorder.ring[(w - 1) % self.recorder.n] if w else np.full(F.N_REC, np.nan)
        code = int(st[L.S_FAULT])
        err = self.loop_error
        return {
            "running": self.running,
            "clock": self.clock,
            "fs_hz": self.fs,
            "seq": int(st[L.S_SEQ]),
            "t_s": st[L.S_SEQ] / self.fs,
            "loop_error": repr(err) if err is not None else None,
            "fault": {"code": code, "name": FC.fault_name(code),
                      "text": self.supervisor.fault_text(code, int(st[L.S_FAULT_DETAIL]))
                      if code else "",
                      "seq": int(st[L.S_FAULT_SEQ]) if code else None},
            "controller": {"loaded": self.controller is not None,
                           "source": getattr(self.controller, "source", None),
                           "order": int(s.prm[L.P_KN]),
                           # enabled: K∞ really in the loop (what the recording's k_on says);
                           # requested: the operator's enable, overridden while a fault is
                           # latched and cleared by fault.reset
                           "enabled": bool(st[L.S_K_TARGET]) and code == 0,
                           "requested": bool(st[L.S_K_TARGET]),
                           "blend": float(st[L.S_RAMP]),
                           "p_eq_um": [float(st[L.S_PEQ_X]), float(st[L.S_PEQ_Y])]},
            "last_frame": {n: float(last[F.REC[n]]) for n in
                           ("e_x", "e_y", "u_x", "u_y", "r_x", "r_y", "omega_rpm", "p_inj_bar")},
            # what `op` last applied (the measured Ω and P_I above follow it at their pace)
            "set_point": self.set_point.status(),
            "recorder": {"written": w, "consumed": int(st[L.S_RD]),
                         "dropped": int(st[L.S_DROPPED]), "ring_frames": self.recorder.n,
                         "writer_pid": self.recorder.writer_pid, **self.recorder.state()},
            "overruns": self.rt.overruns,
            "drivers": {"fast": {"name": getattr(self.fast, "name", "?"),
                                 "drv_status": _bits(st[L.S_Y + F.IN_STATUS]),
                                 **self.fast.counters()},
                        "slow": [{"name": d.name, **d.counters()} for d in self.slow]},
        }

    def timing(self) -> dict[str, Any]:
        """Timing statistics: real-time percentiles (µs) and overruns, or lock-step speed."""
        if self.clock == "lockstep":
            wall, n = self.lockstep.wall_s, self.lockstep.cycles
            return {"clock": "lockstep", "cycles": n, "wall_s": wall,
                    "cycles_per_s": n / wall if wall > 0 else 0.0,
                    "realtime_factor": n / wall / self.fs if wall > 0 else 0.0}
        h = self.state.hist
        return summary(h, overruns=self.rt.overruns, skipped=self.rt.skipped,
                       cycles=int(h[L.H_LATE, L.H_COUNT]))

    def faults(self) -> list[dict]:
        """Every fault latched since start (oldest first)."""
        return self.supervisor.history()

    # --- running ----------------------------------------------------------------------
    def _check_alive(self) -> None:
        if self.loop_error is not None:
            raise RuntimeError(f"the loop died ({self.loop_error!r}); outputs are safe, "
                               f"restart it")

    def _runner(self):
        return self.rt if self.clock == "realtime" else self.lockstep

    def start(self) -> None:
        """Start the loop thread: the real-time clock, or lock-step running continuously."""
        self._check_alive()
        if not self._opened:
            self.open()
        runner = self._runner()
        if not runner.started:
            runner.start(self._stop)

    def run_cycles(self, n: int) -> int:
        """Run ``n`` cycles: lock-step in this thread, or wait n/fs on the real-time loop.

        Returns the cycles run (fewer if ``stop()`` was called).
        """
        self._check_alive()
        if not self._opened:
            self.open()
        if self.clock == "realtime" and not self.rt.started:
            self.start()
        if self._runner().started:
            seq0 = self.state.seq
            self._stop.wait(n / self.fs)
            return self.state.seq - seq0
        with self.lockstep.lock:
            return self.lockstep.run(int(n), None, self._stop)

    def wait_cycles(self, n: int, timeout: float) -> int:
        """Block until the running loop has run ``n`` more cycles, is stopped, or ``timeout``
        s have passed; returns the cycles run meanwhile.

        A condition on the cycle counter, not ``n / fs`` of wall time: a loaded machine may
        run far fewer cycles per second than ``fs`` (``timeout`` only bounds a hung loop).
        """
        seq0 = self.state.seq
        end = time.monotonic() + float(timeout)
        while self.state.seq - seq0 < n and time.monotonic() < end:
            if self._stop.wait(0.001):
                break
        return self.state.seq - seq0

    def run_for(self, seconds: float) -> int:
        """Run for ``seconds`` of loop time (see :meth:`run_cycles`)."""
        return self.run_cycles(int(round(seconds * self.fs)))

    def wait(self, timeout: float | None = None) -> bool:
        """Block until ``stop()`` or the loop's death (or timeout); True if stopped."""
        return self._stop.wait(timeout)

    def start_recording(self, spec: RecordSpec | str | Path) -> Sink:
        """Record every frame from the next cycle on into an HDF5 file, until
        :meth:`stop_recording`.

        The file is created by the writer process first (spawned on the first recording;
        RecordingFailed if it cannot be): the recording starts at the cycle after that.
        """
        sink = self._make_sink(spec, 0)
        self.recorder.add_sink(sink)
        sink.first_seq = self.state.seq
        return sink

    def stop_recording(self, sink: Sink) -> None:
        """Write what the loop produced so far to ``sink`` and close the file."""
        self.recorder.finish(sink)

    def run_segment(self, excitation, *, record=None, events: Sequence = (),
                    controller_on: bool | None = None, pre: int = 0,
                    post: int = 0, stop_on_fault: bool = False) -> SegmentResult:
        """Play ``excitation`` (float64 (n, 2), V added to r_x, r_y) from the next cycle.

        Parameters
        ----------
        record : RecordSpec, path, "memory" or None
            Record the segment's cycles (``pre`` + n + ``post``) to an HDF5 file or memory.
        events : sequence of (cycle_offset, callable)
            Called just before the cycle ``cycle_offset`` counted from the first excitation
            cycle (``-pre <= offset < n + post``); on the real-time clock they run in the
            loop thread and must be quick and non-blocking.
        controller_on : bool, optional
            Enable/disable K∞ at the segment's first cycle; restored afterwards.
        pre, post : int
            Cycles of zero excitation before and after.
        stop_on_fault : bool
            End the segment at the cycle a fault is latched in (at its first cycle if one is
            latched already): the recording is closed after that cycle and the result's
            ``fault`` names it (experiments). Without it the segment plays to its end in the
            safe state.
        """
        full, evs = segment_inputs(excitation, events, pre, post)
        self._check_alive()
        if not self._opened:
            self.open()
        if self.clock == "realtime" and not self.rt.started:
            self.start()      # before the sink exists: it is made once, below
        sink = None if record is None else self._make_sink(record, len(full))
        seg = Segment(full, evs, sink, controller_on, stop_on_fault)
        if sink is not None:
            self.recorder.add_sink(sink)
        n_fault0 = len(self.faults())
        try:
            runner = self._runner()
            if runner.started:
                if not self.player.offer(seg):
                    raise InputError("another segment is playing")
                # the loop thread only flags a segment a fault ended: finished here
                while not seg.done.wait(0.02) and not seg.fault_code:
                    if not runner.alive:
                        self.player.abort("the loop thread stopped during the segment")
            else:
                with self.lockstep.lock:
                    self.lockstep.run(seg.n, seg, self._stop)
                    if seg.i >= seg.n and not seg.fault_code:
                        seg.finish(self.commands)
            if seg.fault_code:
                seg.finish_faulted(self.commands)
            if seg.error is not None:
                raise seg.error
        finally:
            if sink is not None:
                if seg.last_seq < 0:
                    seg.last_seq = max(seg.first_seq + seg.i - 1, -1)
                self.supervisor.poll()
                self.recorder.finish(sink, seg.last_seq)
        faults = self.faults()
        return SegmentResult(seg.first_seq, seg.last_seq, seg.last_seq - seg.first_seq + 1,
                             str(sink.path) if isinstance(sink, FileSink) else None,
                             sink.frames if isinstance(sink, MemorySink) else None,
                             faults[n_fault0:], seg.fault_event(faults, self.state.st))

    def cancel_segment(self, why: str) -> bool:
        """End the segment playing now at the next cycle (any thread): its excitation stops
        and its recording closes after that cycle; ``run_segment`` returns what was played.
        For a segment whose owner is gone (the experiment process died). False when no
        segment is playing."""
        return self.player.cancel(why)

    def close(self) -> None:
        """Stop the loop, put safe outputs on the valves, flush and close recordings, release
        the drivers (deactivate with the safe drive, then clean up)."""
        self._stop.set()
        self.rt.join(10.0)
        self.lockstep.join(10.0)
        if not self._opened:
            return
        self._opened = False
        try:
            try:
                self.fast.deactivate(self.state.safe_drive)
            except Exception as exc:  # noqa: BLE001 - logged; the device's hold is the backstop
                self.log.error("could not write safe outputs", error=str(exc))
        finally:
            try:
                self.fast.cleanup()
            finally:
                for d in self.slow:
                    try:
                        d.cleanup()
                    except Exception as exc:  # noqa: BLE001
                        self.log.error("slow driver close failed", driver=d.name,
                                       error=str(exc))
                self.supervisor.join(2.0)
                self.recorder.close()

    # --- internals ------------------------------------------------------------------------
    def _recorder_failed(self, exc: BaseException) -> None:
        self.supervisor.recorder_failed(exc)

    def _make_sink(self, record, n_expected: int) -> Sink:
        w = int(self.state.st[L.S_W])
        last = self.recorder.ring[(w - 1) % self.recorder.n] if w else None
        return make_sink(record, n_expected, fs=self.fs, config=self.config,
                         config_text=self.loaded.text, last_frame=last,
                         controller=self.controller)


def _bits(v: float) -> int | None:
    """A status word from the frame as an int (None if the driver delivered a non-finite one)."""
    return int(v) if np.isfinite(v) else None
