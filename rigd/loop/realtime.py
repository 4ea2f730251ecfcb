"""The real-time runner of :class:`rigd.loop.loop.ControlLoop`: one cycle per period.

The loop thread sets itself up (SCHED_FIFO, mlockall, CPU pinning, gc frozen; see
:mod:`rigd.loop.clock`), then per period: wait for the deadline (sleep, then spin) → fast
driver ``read`` → commands/segment bookkeeping → :func:`rigd.loop.cycle.rt_cycle` → fast
driver ``write`` → publish the frame to the recorder → overrun accounting (skip or catch up).
"""

from __future__ import annotations

import collections
import sys
import time

import numpy as np

from rigd.loop import clock as CLK
from rigd.loop import cycle as K
from rigd.loop import faults as FC
from rigd.loop import layout as L

_NO_EXC = np.zeros((1, 2))


class RealTimeRunner:
    """Mixin of ControlLoop: the real-time loop thread."""

    # real time --------------------------------------------------------------------------
    def _rt_main(self) -> None:
        cfg = self.config.clock
        problems = CLK.try_realtime(cfg.priority, cfg.cpu)
        if not any("SCHED_FIFO" in p for p in problems):
            # the helper threads share the GIL with the loop: run them just below it, or a
            # preempted helper holding the GIL would stall the loop (priority inversion)
            helpers = [self.recorder._thread, self._monitor, *self._slow_threads]
            CLK.boost_threads([t.native_id for t in helpers if t is not None],
                              max(1, cfg.priority - 1))
        if problems:
            self.rt_warnings = problems
            self.log.warning("real-time scheduling not fully available, running best-effort",
                             problems="; ".join(problems))
        old_si = CLK.fast_switch_interval()
        t0 = time.perf_counter()
        CLK.freeze_gc()
        self.setup_s = time.perf_counter() - t0
        try:
            self._rt_loop()
        except BaseException as exc:  # never die silently: safe state and log
            self.st[L.S_EXT_FAULT] = FC.DRIVER_EXCEPTION
            self.log.error("loop thread crashed", error=repr(exc))
            raise
        finally:
            CLK.thaw_gc()
            sys.setswitchinterval(old_si)
            CLK.drop_realtime()

    def _rt_loop(self) -> None:
        cfg, sup = self.config.clock, self.config.supervisor
        fin, prm, st, drive, ring, hist = (self.fin, self.prm, self.st, self.drive,
                                           self.recorder.ring, self.hist)
        read, write, rt_cycle = self.fast.read, self.fast.write, K.rt_cycle
        publish, cmds, stop = self.recorder.publish, self._cmds, self._stop
        perf, wait_until = time.perf_counter_ns, CLK.wait_until
        period = int(round(1e9 / self.fs))
        spin = int(cfg.spin_us * 1000)
        skip = cfg.overrun == "skip"
        storm: collections.deque = collections.deque(maxlen=sup.overrun_storm_count)
        storm_ns = int(sup.overrun_storm_window_s * 1e9)
        S_W = L.S_W
        prev = -1
        t_setup = perf()
        nxt = t_setup + period
        self._started.set()
        while not stop.is_set():
            wake = wait_until(nxt, spin)
            try:
                read(fin)
            except Exception as exc:
                self._driver_failed(exc)
            seg = self._seg
            if seg is not None:
                if seg.first_seq < 0:
                    self._seg_begin(seg)
                self._fire_events(seg)
            if cmds or self._pending_ctrl is not None:
                self._apply_commands()
            if seg is None:
                rt_cycle(fin, prm, st, drive, ring, _NO_EXC, -1, hist, wake - nxt, prev)
            else:
                rt_cycle(fin, prm, st, drive, ring, seg.exc, seg.i, hist, wake - nxt, prev)
                seg.i += 1
                if seg.i >= seg.n:
                    self._seg = None
                    self._seg_finish(seg)
            try:
                write(drive)
            except Exception as exc:
                self._driver_failed(exc)
            publish(int(st[S_W]))
            done = perf()
            prev = done - wake
            nxt += period
            if done > nxt:
                self.overruns += 1
                storm.append(done)
                if len(storm) == storm.maxlen and done - storm[0] <= storm_ns:
                    st[L.S_EXT_FAULT] = FC.OVERRUN_STORM
                    storm.clear()
                if skip:
                    missed = (done - nxt) // period + 1
                    nxt += missed * period
                    self.skipped += missed
        seg = self._seg
        if seg is not None:
            self._seg = None
            seg.error = RuntimeError("loop stopped during the segment")
            seg.done.set()
