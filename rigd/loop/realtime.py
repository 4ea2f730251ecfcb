"""The real-time clock: a loop thread running one cycle per period.

The loop thread sets itself up (SCHED_FIFO, mlockall, CPU pinning, gc frozen; see
:mod:`rigd.loop.clock`), then per period: wait for the deadline (sleep, then spin) → fast
driver ``read`` → segment bookkeeping and queued commands → :func:`rigd.loop.cycle.rt_cycle`
(a segment played with ``stop_on_fault`` is flagged as ended when a fault is latched) → fast
driver ``write`` → publish the frame to the recorder → overrun accounting (skip or
catch up; the kernel measures the gaps between cycles: a stall latches ``loop_stall``, lost
control time beyond its bound ``overrun_storm``, :mod:`rigd.loop.liveness`).

If anything in the loop thread raises, the supervisor puts the outputs in the safe state at
once, latches ``loop_died`` and stops the loop (:meth:`rigd.loop.supervisor.Supervisor.loop_died`).
"""

from __future__ import annotations

import collections
import sys
import threading
import time

from rigd.loop import clock as CLK
from rigd.loop import cycle as C
from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop.safeword import W_CYCLE_NS
from rigd.loop.segment import NO_EXCITATION


class RealTimeClock:
    """Owner of the real-time loop thread and its timing counters.

    Parameters
    ----------
    config : rigd.rigconfig.RigConfig
    parts : rigd.loop.loop.ControlLoop
        Provides ``state``, ``commands``, ``player``, ``recorder``, ``fast``, ``supervisor``,
        ``requests``, ``slow_pollers`` and ``log`` (each owned there, used here).
    """

    def __init__(self, config, parts) -> None:
        self._cfg = config.clock
        self._sup = config.supervisor
        self._p = parts
        self.fs = config.loop.fs_hz
        self.overruns = 0
        self.skipped = 0
        self.rt_warnings: list[str] = []
        self.setup_s = 0.0
        #: SCHED_FIFO priority of the helper threads while the loop runs with SCHED_FIFO
        #: (None: not real-time), for threads preparing work for the loop (clock.boosted)
        self.helper_priority: int | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def started(self) -> bool:
        return self._thread is not None

    def start(self, stop: threading.Event) -> None:
        """Start the loop thread; returns once the first cycle is due (any thread)."""
        self._thread = threading.Thread(target=self._main, args=(stop,), name="rigd-loop",
                                        daemon=True)
        self._thread.start()
        self._started.wait(30.0)

    def join(self, timeout: float) -> None:
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    # --- the loop thread ---------------------------------------------------------------
    def _main(self, stop: threading.Event) -> None:
        cfg, p = self._cfg, self._p
        problems = CLK.try_realtime(cfg.priority, cfg.cpu)
        if not any("SCHED_FIFO" in x for x in problems):
            # the helper threads share the GIL with the loop: run them just below it, or a
            # preempted helper holding the GIL would stall the loop (priority inversion)
            helpers = [p.recorder.native_id, p.recorder.link_native_id, p.supervisor.native_id,
                       *p.slow_pollers.native_ids]
            self.helper_priority = max(1, cfg.priority - 1)
            CLK.boost_threads([t for t in helpers if t is not None], self.helper_priority)
        if any(x.startswith("mlockall") for x in problems):
            p.recorder.shared.populate()          # else mlockall has faulted the ring in
        if problems:
            self.rt_warnings = problems
            p.log.warning("real-time scheduling not fully available, running best-effort",
                          problems="; ".join(problems))
        old_si = CLK.fast_switch_interval()
        t0 = time.perf_counter()
        CLK.freeze_gc()
        self.setup_s = time.perf_counter() - t0
        try:
            self._loop(stop)
        except BaseException as exc:  # noqa: BLE001 - never die silently: safe state, latch
            p.supervisor.loop_died(exc, p.fast, stop)
        finally:
            self.helper_priority = None
            self._started.set()
            p.player.abort("loop stopped during the segment")
            CLK.thaw_gc()
            sys.setswitchinterval(old_si)
            CLK.drop_realtime()

    def _loop(self, stop: threading.Event) -> None:
        """The cycles, one per period, until ``stop``.

        Runs in: loop thread — per cycle O(1), no array allocation, never blocks except the
        deadline wait (drivers' read/write must honour the same contract).
        """
        cfg, sup, p = self._cfg, self._sup, self._p
        s = p.state
        fin, prm, st, drive, hist = s.fin, s.prm, s.st, s.drive, s.hist
        ring = p.recorder.ring
        sw = p.safe.word          # attached to its shared file (if any) before the start
        read, write, rt_cycle, take_safe = p.fast.read, p.fast.write, C.rt_cycle, C.take_safe
        publish = p.recorder.publish
        commands, cq, player = p.commands, p.commands.queue, p.player
        driver_failed = p.supervisor.driver_failed
        post = p.requests.post_from_loop
        perf, wait_until = time.perf_counter_ns, CLK.wait_until
        period = int(round(1e9 / self.fs))
        spin = int(cfg.spin_us * 1000)
        skip = cfg.overrun == "skip"
        # the former count rule, only when configured (the lost-time rule in the kernel,
        # rigd.loop.liveness, is the overrun storm's meaning)
        count = sup.overrun_storm_count
        storm: collections.deque | None = (collections.deque(maxlen=count) if count else None)
        storm_ns = int(p.liveness.storm_window_s * 1e9)
        # like the lost-time rule, the count rule measures nothing in the start-up grace
        # (rigd.loop.liveness.GRACE_S: first calls of every code path, page faults)
        grace_n = prm[L.P_GRACE_N]
        S_W, S_FAULT, S_SEQ = L.S_W, L.S_FAULT, L.S_SEQ
        prev = -1
        sw[W_CYCLE_NS] = 0        # no gap measured across a start
        nxt = perf() + period
        self._started.set()
        while not stop.is_set():
            wake = wait_until(nxt, spin)
            try:
                read(fin)
            except Exception as exc:  # noqa: BLE001 - a driver fault, not a loop death
                driver_failed(exc)
            seg = player.current
            if seg is not None:
                if seg.first_seq < 0:
                    seg.begin(st, commands)
                if seg.events:
                    seg.fire_events()
            if cq or commands.swap is not None:
                take_safe(sw, st)     # a SAFE requested by now overtakes what is queued
                commands.apply()
            if seg is None:
                rt_cycle(fin, prm, st, drive, ring, NO_EXCITATION, -1, hist, wake - nxt, prev,
                         sw, wake)
            else:
                rt_cycle(fin, prm, st, drive, ring, seg.exc, seg.i, hist, wake - nxt, prev, sw,
                         wake)
                seg.i += 1
                if seg.stop_on_fault and st[S_FAULT] != 0.0:
                    player.stopped_for_fault(seg, st)     # flag only: the caller finishes it
                elif seg.i >= seg.n:
                    player.finished(seg, commands)
                elif seg.cancelled:                       # its owner is gone
                    player.cancelled(seg, commands)
            try:
                write(drive)
            except Exception as exc:  # noqa: BLE001
                driver_failed(exc)
            publish(int(st[S_W]))
            done = perf()
            prev = done - wake
            nxt += period
            if done > nxt:
                self.overruns += 1
                if storm is not None and st[S_SEQ] >= grace_n:
                    storm.append(done)
                    if len(storm) == storm.maxlen and done - storm[0] <= storm_ns:
                        post(FC.OVERRUN_STORM)
                        storm.clear()
                if skip:
                    missed = (done - nxt) // period + 1
                    nxt += missed * period
                    self.skipped += missed
