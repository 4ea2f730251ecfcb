"""The runners of :class:`rigd.loop.loop.ControlLoop`: real-time thread, lock-step batches,
segments (excitation + recording + events) and clean shutdown.

Kept apart from loop.py (state, commands, queries) so each file has one job.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigd.errors import InputError
from rigd.frame import REC
from rigd.loop import cycle as K
from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop.realtime import RealTimeRunner
from rigd.loop.sinks import H5Sink, MemorySink, RecordSpec, Sink

_NO_EXC = np.zeros((1, 2))


@dataclass
class SegmentResult:
    """What ``run_segment`` played: frames ``first_seq..last_seq`` (inclusive).

    ``frames`` holds the recorded frames for ``record="memory"``; ``faults`` the faults that
    latched during the segment.
    """

    first_seq: int
    last_seq: int
    n_frames: int
    path: str | None = None
    frames: np.ndarray | None = None
    faults: list | None = None


class _Segment:
    def __init__(self, exc: np.ndarray, events, sink: Sink | None, controller_on):
        self.exc = exc
        self.n = len(exc)
        self.i = 0
        self.events = collections.deque(sorted(events, key=lambda e: e[0]))
        self.sink = sink
        self.controller_on = controller_on
        self.prev_target: float | None = None
        self.first_seq = -1
        self.last_seq = -1
        self.done = threading.Event()
        self.error: BaseException | None = None


class LoopRunner(RealTimeRunner):
    """Mixin of ControlLoop: how the cycles are driven."""

    # --- public ----------------------------------------------------------------------------
    def start(self) -> None:
        """Start the loop thread: the real-time clock, or lock-step running continuously."""
        if not self._opened:
            self.open()
        if self._thread is not None:
            return
        target = self._rt_main if self.clock == "realtime" else self._lockstep_main
        self._started = threading.Event()
        self._thread = threading.Thread(target=target, name="rigd-loop", daemon=True)
        self._thread.start()
        self._started.wait(30.0)        # returns once the first cycle is due

    def run_cycles(self, n: int) -> int:
        """Run ``n`` cycles: lock-step in this thread, or wait n/fs on the running real-time loop.

        Returns the cycles run (fewer if ``stop()`` was called).
        """
        if not self._opened:
            self.open()
        if self._thread is not None:
            seq0 = int(self.st[L.S_SEQ])
            self._stop.wait(n / self.fs)
            return int(self.st[L.S_SEQ]) - seq0
        if self.clock == "realtime":
            self.start()
            return self.run_cycles(n)
        with self._lock:
            return self._lockstep_cycles(int(n), None)

    def run_for(self, seconds: float) -> int:
        """Run for ``seconds`` of loop time (see :meth:`run_cycles`)."""
        return self.run_cycles(int(round(seconds * self.fs)))

    def wait(self, timeout: float | None = None) -> bool:
        """Block until ``stop()`` (or timeout); True if stopped."""
        return self._stop.wait(timeout)

    def start_recording(self, spec: RecordSpec | str | Path) -> Sink:
        """Record every frame from the next cycle on into an HDF5 file, until
        :meth:`stop_recording`."""
        sink = self._make_sink(spec, 0)
        sink.first_seq = int(self.st[L.S_SEQ])
        return self.recorder.add_sink(sink)

    def stop_recording(self, sink: Sink) -> None:
        """Write what the loop produced so far to ``sink`` and close the file."""
        self.recorder.finish(sink)

    def run_segment(self, excitation, *, record=None, events: Sequence = (),
                    controller_on: bool | None = None, pre: int = 0,
                    post: int = 0) -> SegmentResult:
        """Play ``excitation`` (float64 (n, 2), V added to r_x, r_y) from the next cycle.

        Parameters
        ----------
        record : RecordSpec, path, "memory" or None
            Record the segment's cycles (``pre`` + n + ``post``) to an HDF5 file or memory.
        events : sequence of (cycle_offset, callable)
            Called just before the cycle ``cycle_offset`` counted from the first excitation
            cycle (``-pre <= offset < n + post``).
        controller_on : bool, optional
            Enable/disable K∞ at the segment's first cycle; restored afterwards.
        pre, post : int
            Cycles of zero excitation before and after.
        """
        exc = np.asarray(excitation, dtype=float)
        if exc.ndim != 2 or exc.shape[1] != 2:
            raise InputError(f"excitation must be an (n, 2) array of [r_x, r_y] volts, got shape "
                             f"{exc.shape}")
        if not np.all(np.isfinite(exc)):
            raise InputError("excitation contains NaN or Inf")
        if pre < 0 or post < 0:
            raise InputError("pre and post must be >= 0 cycles")
        full = np.zeros((pre + len(exc) + post, 2))
        full[pre:pre + len(exc)] = exc
        evs = []
        for off, fn in events:
            idx = pre + int(off)
            if not 0 <= idx < len(full):
                raise InputError(f"event at cycle offset {off} is outside the segment "
                                 f"[-{pre}, {len(exc) + post})")
            evs.append((idx, fn))
        if not self._opened:
            self.open()
        sink = None if record is None else self._make_sink(record, len(full))
        seg = _Segment(full, evs, sink, controller_on)
        if sink is not None:
            self.recorder.add_sink(sink)
        n_fault0 = len(self.faults())
        try:
            if self._thread is not None:
                if self._seg is not None:
                    raise InputError("another segment is playing")
                self._seg = seg
                while not seg.done.wait(0.05):
                    if self._thread is None or not self._thread.is_alive():
                        raise RuntimeError("the loop thread stopped during the segment")
            else:
                if self.clock == "realtime":
                    self.start()
                    return self.run_segment(excitation, record=record, events=events,
                                            controller_on=controller_on, pre=pre, post=post)
                with self._lock:
                    self._lockstep_cycles(seg.n, seg)
                    if seg.i >= seg.n:
                        self._seg_finish(seg)
            if seg.error is not None:
                raise seg.error
        finally:
            if sink is not None:
                if seg.last_seq < 0:
                    seg.last_seq = max(seg.first_seq + seg.i - 1, -1)
                self._poll_faults()
                self.recorder.finish(sink, seg.last_seq)
        return SegmentResult(seg.first_seq, seg.last_seq, seg.last_seq - seg.first_seq + 1,
                             str(sink.path) if isinstance(sink, H5Sink) else None,
                             sink.frames if isinstance(sink, MemorySink) else None,
                             self.faults()[n_fault0:])

    def close(self) -> None:
        """Stop the loop, put safe outputs on the valves, flush and close recordings, close
        drivers."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(10.0)
            self._thread = None
        if not self._opened:
            return
        self._opened = False
        try:
            self._safe_outputs()
        finally:
            try:
                self.fast.close()
            finally:
                for d in self.slow:
                    try:
                        d.close()
                    except Exception as exc:
                        self.log.error("slow driver close failed", driver=d.name, error=str(exc))
                if self._monitor is not None:
                    self._monitor.join(2.0)
                self._poll_faults()
                self.recorder.close()

    # --- internals ------------------------------------------------------------------------
    def _safe_outputs(self) -> None:
        lo, hi = self.config.loop.drive_v
        r0 = self.config.loop.r0_v
        for i, v in enumerate(self.config.valves):
            self.drive[i] = min(max(v.kff * r0, lo), hi)
        try:
            self.fast.write(self.drive)
        except Exception as exc:
            self.log.error("could not write safe outputs", error=str(exc))

    def _make_sink(self, record, n_expected: int) -> Sink:
        if isinstance(record, str) and record == "memory":
            return MemorySink(n_expected)
        spec = record if isinstance(record, RecordSpec) else RecordSpec(record)
        w = int(self.st[L.S_W])
        last = self.recorder.ring[(w - 1) % self.recorder.n] if w else None
        plant = self.config.plant or {}
        meta: dict[str, Any] = {"kind": "run", "omega_rpm": plant.get("omega_rpm", 0.0),
                                "p_inj_bar": plant.get("p_inj_bar", float("nan"))}
        if last is not None and np.isfinite(last[REC["omega_rpm"]]):
            meta["omega_rpm"] = float(last[REC["omega_rpm"]])
        if last is not None and np.isfinite(last[REC["p_inj_bar"]]):
            meta["p_inj_bar"] = float(last[REC["p_inj_bar"]])
        if self.controller is not None:
            meta["controller"] = str(self.controller.source)
        meta.update(spec.meta)
        return H5Sink(spec.path, fs=self.fs, meta=meta, config_text=self.loaded.text,
                      chunk_frames=self.config.recorder.chunk_frames)

    def _seg_begin(self, seg: _Segment) -> None:
        st = self.st
        seg.first_seq = int(st[L.S_SEQ])
        if seg.sink is not None:
            seg.sink.first_seq = seg.first_seq
        if seg.controller_on is not None:
            seg.prev_target = float(st[L.S_K_TARGET])
            self._cmds.append(("enable", bool(seg.controller_on)))
            self._apply_commands()

    def _seg_finish(self, seg: _Segment) -> None:
        seg.last_seq = seg.first_seq + seg.n - 1
        if seg.prev_target is not None:
            self._cmds.append(("enable", bool(seg.prev_target)))
        seg.done.set()

    def _fire_events(self, seg: _Segment) -> None:
        while seg.events and seg.events[0][0] <= seg.i:
            _, fn = seg.events.popleft()
            try:
                fn()
            except Exception as exc:
                seg.error = exc

    def _driver_failed(self, exc: BaseException) -> None:
        if self._driver_error is None:
            self._driver_error = exc
        self.st[L.S_EXT_FAULT] = FC.DRIVER_EXCEPTION

    # lock-step --------------------------------------------------------------------------
    def _lockstep_main(self) -> None:
        self._started.set()
        while not self._stop.is_set():
            seg = self._seg
            if seg is not None:
                self._lockstep_cycles(seg.n, seg)
                self._seg = None
                if seg.i >= seg.n:
                    self._seg_finish(seg)
                else:
                    seg.error = RuntimeError("loop stopped during the segment")
                    seg.done.set()
            else:
                self._lockstep_cycles(self.config.clock.batch_cycles, None)

    def _lockstep_cycles(self, n: int, seg: _Segment | None) -> int:
        st, rec = self.st, self.recorder
        batch = self.config.clock.batch_cycles
        if seg is not None and seg.first_seq < 0:
            self._seg_begin(seg)
        done = 0
        t0 = time.perf_counter()
        while done < n and not self._stop.is_set():
            if seg is not None:
                self._fire_events(seg)
            self._apply_commands()
            m = min(n - done, batch)
            if self._pending_ctrl is not None:   # blending out for a swap: stop when at 0
                m = min(m, int(st[L.S_RAMP] / self.prm[L.P_RAMP_STEP]) + 1)
            exc, ei = _NO_EXC, -1
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
            if self._seen_faults < st[L.S_NFAULT]:
                self._poll_faults()
        self._lock_cycles += done
        self._lock_wall += time.perf_counter() - t0
        return done

    def _step(self, m: int, exc: np.ndarray, ei: int) -> int:
        """``m`` lock-step cycles (fewer if the ring fills): compiled batch or per-cycle."""
        if self._pk is not None:
            f = self.fast
            if getattr(self, "_batch", None) is None:
                try:
                    K.lockstep_batch(self._pk, f.state, f.params, self.fin, self.prm, self.st,
                                     self.drive, self.recorder.ring, exc, ei, 0)
                    self._batch = K.lockstep_batch
                except Exception:  # a plant kernel of another signature: generic variant
                    self._batch = K.lockstep_batch_generic
            return int(self._batch(self._pk, f.state, f.params, self.fin, self.prm, self.st,
                                   self.drive, self.recorder.ring, exc, ei, m))
        st, fin, prm, drive, ring = self.st, self.fin, self.prm, self.drive, self.recorder.ring
        for k in range(m):
            if st[L.S_W] - st[L.S_RD] >= self.recorder.n:
                return k
            try:
                self.fast.read(fin)
            except Exception as exc_:
                self._driver_failed(exc_)
            if ei >= 0:
                K.cycle(fin, prm, st, drive, ring, exc[ei + k, 0], exc[ei + k, 1])
            else:
                K.cycle(fin, prm, st, drive, ring, 0.0, 0.0)
            try:
                self.fast.write(drive)
            except Exception as exc_:
                self._driver_failed(exc_)
        return m
