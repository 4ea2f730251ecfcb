"""The lock-step (virtual) clock: batches of cycles as fast as the CPU allows.

With the simulated plant (a fast driver exposing its compiled ``kernel``, ``state`` and
``params``) a whole batch of cycles runs inside one compiled call together with the plant's
step (:func:`rigd.loop.cycle.lockstep_batch`, without the GIL); with any other driver the
cycles run one by one with ``read``/``write``. Commands, segment events and fault polling are
handled between batches, so a batch stops at the next event, at a controller swap's blend-out,
at the cycle a fault is latched in, and whenever the recorder ring is full (lock-step never
drops a frame: it waits for the writer).
"""

from __future__ import annotations

import threading
import time

import numpy as np

from rigd.frame import N_REC
from rigd.loop import cycle as C
from rigd.loop import layout as L
from rigd.loop.safeword import W_CYCLE_NS
from rigd.loop.segment import NO_EXCITATION


class LockstepClock:
    """Owner of the lock-step runner: batch kernel choice, one-runner lock, speed counters.

    Parameters
    ----------
    config : rigd.rigconfig.RigConfig
    parts : rigd.loop.loop.ControlLoop
        Provides ``state``, ``commands``, ``player``, ``recorder``, ``fast``, ``supervisor``
        (each owned there, used here).
    """

    def __init__(self, config, parts) -> None:
        self._batch_cycles = config.clock.batch_cycles
        self._p = parts
        fast = parts.fast
        self._pk = getattr(fast, "kernel", None)
        self._batch = None          # chosen by warm_up(): cached or generic batch kernel
        #: one runner at a time (the caller's thread, or the continuous lock-step thread)
        self.lock = threading.Lock()
        self.cycles = 0
        self.wall_s = 0.0
        self._thread: threading.Thread | None = None

    @property
    def compiled_plant(self) -> bool:
        """The plant runs inside the compiled batch (its kernel, state and params exist)."""
        f = self._p.fast
        return self._pk is not None and hasattr(f, "state") and hasattr(f, "params")

    def warm_up(self) -> None:
        """Compile or load the batch kernel now (scratch arrays, zero cycles)."""
        if not self.compiled_plant:
            return
        s, f = self._p.state, self._p.fast
        ring = np.zeros((4, N_REC))
        try:
            C.lockstep_batch(self._pk, f.state.copy(), f.params.copy(), s.fin.copy(),
                             s.prm.copy(), s.st.copy(), s.drive.copy(), ring, NO_EXCITATION,
                             -1, 0, self._p.safe.word.copy())
            self._batch = C.lockstep_batch
        except Exception:  # noqa: BLE001 - a plant kernel of another signature: generic variant
            self._batch = C.lockstep_batch_generic

    # --- runners ---------------------------------------------------------------------------
    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def started(self) -> bool:
        return self._thread is not None

    def start(self, stop: threading.Event) -> None:
        """Run lock-step continuously in a thread of its own (``ControlLoop.start``)."""
        started = threading.Event()
        self._thread = threading.Thread(target=self._main, args=(stop, started),
                                        name="rigd-loop", daemon=True)
        self._thread.start()
        started.wait(30.0)

    def join(self, timeout: float) -> None:
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def _main(self, stop: threading.Event, started: threading.Event) -> None:
        p = self._p
        started.set()
        try:
            while not stop.is_set():
                seg = p.player.current
                if seg is not None:
                    self.run(seg.n, seg, stop)
                    if seg.fault_code:
                        p.player.current = None       # its caller finishes it
                    elif seg.i >= seg.n:
                        p.player.finished(seg, p.commands)
                    else:
                        p.player.abort("loop stopped during the segment")
                else:
                    self.run(self._batch_cycles, None, stop)
        except BaseException as exc:  # noqa: BLE001 - this thread's death: never silent
            if p.supervisor.loop_error is None:       # (run() handled an Exception already)
                p.supervisor.loop_died(exc, p.fast, stop)
        finally:
            p.player.abort("loop stopped during the segment")

    def run(self, n: int, seg, stop: threading.Event) -> int:
        """Run up to ``n`` cycles in this thread (the caller holds :attr:`lock` or is the
        lock-step thread); returns the cycles run. An exception makes the outputs safe,
        latches ``loop_died`` and stops the loop before it propagates.

        Runs in: the thread running the cycles — between batches it applies commands, fires
        events and polls faults; it blocks only when the recorder ring is full.
        """
        p = self._p
        try:
            return self._run(n, seg, stop)
        except Exception as exc:
            # a KeyboardInterrupt (Ctrl-C in the caller's thread) is the caller stopping the
            # run, not the loop dying: it propagates and close() makes the outputs safe
            p.supervisor.loop_died(exc, p.fast, stop)
            raise

    def _run(self, n: int, seg, stop: threading.Event) -> int:
        p = self._p
        st, rec, commands, sup = p.state.st, p.recorder, p.commands, p.supervisor
        ramp_step = p.state.prm[L.P_RAMP_STEP]
        batch = self._batch_cycles
        if seg is not None and seg.first_seq < 0:
            seg.begin(st, commands)
        done = 0
        t0 = time.perf_counter()
        halt = seg is not None and seg.stop_on_fault
        while done < n and not stop.is_set():
            if seg is not None:
                seg.fire_events()
            if commands:
                C.take_safe(p.safe.word, st)   # a SAFE requested by now overtakes the queue
            commands.apply()
            m = min(n - done, batch)
            if halt and st[L.S_FAULT] != 0.0:    # latched before: play one cycle, stop below
                m = 1
            if commands.swap is not None:   # blending out for a swap: stop when at 0
                m = min(m, int(st[L.S_RAMP] / ramp_step) + 1)
            exc, ei = NO_EXCITATION, -1
            if seg is not None:
                if seg.events:
                    m = min(m, max(seg.events[0][0] - seg.i, 1))
                exc, ei = seg.exc, seg.i
            if st[L.S_W] - st[L.S_RD] >= rec.n:
                rec.wait_free()
            k = self._step(m, exc, ei)
            done += k
            if seg is not None:
                seg.i += k
            rec.publish(int(st[L.S_W]))
            p.safe.word[W_CYCLE_NS] = time.monotonic_ns()   # the loop's age, for status
            if sup.unseen:
                sup.poll()
            if halt and st[L.S_FAULT] != 0.0:    # the batch ends at the latching cycle
                seg.stop_for_fault(st)
                break
            if seg is not None and seg.cancelled and seg.i < seg.n:   # its owner is gone
                seg.stop_cancelled(commands)
                break
        self.cycles += done
        self.wall_s += time.perf_counter() - t0
        return done

    def _step(self, m: int, exc: np.ndarray, ei: int) -> int:
        """``m`` cycles (fewer if the ring fills): compiled batch with the plant, or per cycle."""
        p = self._p
        s = p.state
        if self._batch is not None:
            f = p.fast
            return int(self._batch(self._pk, f.state, f.params, s.fin, s.prm, s.st, s.drive,
                                   p.recorder.ring, exc, ei, m, p.safe.word))
        st, fin, prm, drive, ring = s.st, s.fin, s.prm, s.drive, p.recorder.ring
        read, write, failed = p.fast.read, p.fast.write, p.supervisor.driver_failed
        ring_n = p.recorder.n
        cycle, take_safe, sw = C.cycle, C.take_safe, p.safe.word
        nf = st[L.S_NFAULT]
        for k in range(m):
            if st[L.S_NFAULT] != nf:               # a fault latched: end the batch there
                return k
            if st[L.S_W] - st[L.S_RD] >= ring_n:
                return k
            try:
                read(fin)
            except Exception as exc_:  # noqa: BLE001
                failed(exc_)
            take_safe(sw, st)
            if ei >= 0:
                cycle(fin, prm, st, drive, ring, exc[ei + k, 0], exc[ei + k, 1])
            else:
                cycle(fin, prm, st, drive, ring, 0.0, 0.0)
            try:
                write(drive)
            except Exception as exc_:  # noqa: BLE001
                failed(exc_)
        return m
