"""One experiment at one operating point: plays it on the loop and writes its record(s).

Records are written to ``<name>.h5.part`` by the loop's recorder and renamed to ``<name>.h5``
only when the segment completed: an interrupted point leaves no file behind.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigd.errors import FaultError, InputError
from rigd.experiments import signals
from rigd.experiments.schemas import (
    ChirpSpec,
    ImpactSpec,
    MultilevelSpec,
    MultisineSpec,
    PrbsSpec,
    RunoutSpec,
)


class SegmentFault(FaultError):
    """A fault latched while the experiment played a segment: the segment ended at that
    cycle and the experiment ends (``failed``, the fault named).

    Attributes
    ----------
    fault : dict
        ``seq``, ``code``, ``name``, ``text`` of the latched fault.
    """

    def __init__(self, fault: dict[str, Any], where: str = "") -> None:
        self.fault = dict(fault)
        super().__init__(f"{fault['name']} latched at cycle {fault['seq']}"
                         f"{' during ' + where if where else ''}: {fault['text']}")


def play(loop: Any, exc: np.ndarray, **kw: Any) -> Any:
    """``loop.run_segment(exc, stop_on_fault=True, **kw)``; raises :class:`SegmentFault` if a
    fault ended it (an unrecorded or scratch segment of an experiment)."""
    res = loop.run_segment(exc, stop_on_fault=True, **kw)
    if getattr(res, "fault", None):
        raise SegmentFault(res.fault)
    return res


@dataclass(frozen=True)
class Hit:
    """A simulated hammer blow as a segment event: ``plant.impact(axis, peak_n, pulse_s)``
    when called (in the thread running the cycles). Data, not a closure: the experiment
    process sends it to the loop's process as ``("impact", axis, peak_n, pulse_s)``."""

    plant: Any
    axis: str
    peak_n: float
    pulse_s: float

    def __call__(self) -> None:
        self.plant.impact(self.axis, self.peak_n, self.pulse_s)


class PointFailed(Exception):
    """The point could not be recorded (no hammer hit, not settled, ...): one line."""


def _n(seconds: float, fs: float) -> int:
    return int(round(seconds * fs))


def loop_fs(loop: Any) -> float:
    """The loop rate, Hz."""
    fs = getattr(loop, "fs", None) or getattr(loop, "fs_hz", None)
    if fs is None:
        fs = loop.status().get("fs_hz")
    return float(fs)


def sim_plant(loop: Any) -> Any | None:
    """The simulated plant driver of an in-process loop (has ``impact``), or None."""
    for name in ("fast", "plant", "driver", "fast_driver"):
        d = getattr(loop, name, None)
        if d is not None and callable(getattr(d, "impact", None)):
            return d
    return None


def controller_enabled(loop: Any) -> bool | None:
    """Is K∞ enabled (target state)? None if the loop does not say."""
    try:
        return bool(loop.status()["controller"]["enabled"])
    except (KeyError, TypeError, AttributeError):
        return None


def controller_loaded(loop: Any) -> bool | None:
    try:
        return bool(loop.status()["controller"]["loaded"])
    except (KeyError, TypeError, AttributeError):
        return None


def wants_controller(spec: Any) -> bool:
    """Does the spec record anything with K∞ on?"""
    c = getattr(spec, "controller", False)
    return any(c) if isinstance(c, list) else bool(c)


def check_against_rate(spec: Any, fs: float, where: str) -> None:
    """Refuse requests the loop rate cannot honour (before anything runs)."""
    nyq = fs / 2.0
    if (isinstance(spec, (PrbsSpec, MultilevelSpec)) and spec.min_hold_s is not None
            and spec.min_hold_s < 1.0 / fs * 0.5):
            raise InputError(f"min_hold_s {spec.min_hold_s} is shorter than one loop period "
                             f"(1/{fs:g} s)", f"{where}: min_hold_s")
    if isinstance(spec, MultisineSpec):
        if spec.f_max_hz >= nyq:
            raise InputError(f"f_max_hz must be below the Nyquist frequency {nyq:g} Hz",
                             f"{where}: f_max_hz")
        _, k = signals.multisine_lines(fs, spec.period_s, spec.f_min_hz, spec.f_max_hz,
                                       spec.lines)
        if k.size == 0:
            raise InputError("no frequency line of the grid 1/period_s falls in "
                             "[f_min_hz, f_max_hz]", f"{where}: period_s")
    if isinstance(spec, ChirpSpec) and max(spec.f0_hz, spec.f1_hz) >= nyq:
        raise InputError(f"chirp frequencies must be below the Nyquist frequency {nyq:g} Hz",
                         f"{where}: f1_hz")
    if isinstance(spec, ImpactSpec) and spec.pulse_s < 1.0 / fs:
        raise InputError(f"pulse_s shorter than one loop period (1/{fs:g} s)",
                         f"{where}: pulse_s")


def excitation(spec: Any, fs: float) -> np.ndarray:
    """The (n, 2) excitation of an excitation-kind spec (quiet lead-in included)."""
    common = {"axes": tuple(spec.axes), "lead_in_s": spec.lead_in_s}
    if isinstance(spec, PrbsSpec):
        return signals.prbs(fs, spec.duration_s, spec.amplitude_v,
                            switch_probability=spec.switch_probability,
                            min_hold_s=spec.min_hold_s, seed=spec.seed, **common)
    if isinstance(spec, MultilevelSpec):
        return signals.multilevel(fs, spec.duration_s, spec.amplitude_v, levels=spec.levels,
                                  switch_probability=spec.switch_probability,
                                  min_hold_s=spec.min_hold_s, seed=spec.seed, **common)
    if isinstance(spec, MultisineSpec):
        return signals.multisine(fs, spec.amplitude_v, period_s=spec.period_s,
                                 periods=spec.periods, f_min_hz=spec.f_min_hz,
                                 f_max_hz=spec.f_max_hz, lines=spec.lines, seed=spec.seed,
                                 **common)
    if isinstance(spec, ChirpSpec):
        return signals.chirp(fs, spec.duration_s, spec.amplitude_v, f0_hz=spec.f0_hz,
                             f1_hz=spec.f1_hz, method=spec.method, **common)
    raise TypeError(f"not an excitation spec: {type(spec).__name__}")  # pragma: no cover


def segments(spec: Any) -> int:
    """How many recorded segments a point spec produces (for progress)."""
    if isinstance(spec, ImpactSpec):
        return len(spec.controller) * spec.repeats
    return 1


class PointRunner:
    """Runs one point spec on ``loop`` and registers its files in the manifest."""

    def __init__(self, loop: Any, manifest: Any, fs: float, base_meta: dict[str, Any],
                 tick: Callable[[str], None], should_stop: Callable[[], bool],
                 critical: Callable[[], Any] = contextlib.nullcontext):
        self.loop = loop
        self.manifest = manifest
        self.fs = fs
        self.base_meta = base_meta
        self.tick = tick
        self.should_stop = should_stop
        self.critical = critical
        self._part: Path | None = None

    # -- recording with .part + rename ---------------------------------------------------
    def _record(self, path: Path, meta: dict[str, Any], exc: np.ndarray, *, controller_on: bool,
                events=(), keep: Callable[[Any], None] | None = None) -> Any:
        """Record ``exc`` into ``path`` (via ``.part``); ``keep(result)`` lists it.

        The rename and ``keep`` run inside ``critical()`` (the stop flag's ``deferring``: a
        SIGINT there only sets the flag), so an interrupt leaves either a ``.part`` that is
        discarded or a complete file that the manifest lists — never a complete, unlisted one.
        """
        from rigd.loop.sinks import RecordSpec

        part = path.with_name(path.name + ".part")
        self._part = part
        res = self.loop.run_segment(exc, record=RecordSpec(str(part), meta), events=list(events),
                                    controller_on=controller_on, stop_on_fault=True)
        with self.critical():
            os.replace(part, path)
            self._part = None
            if keep is not None:
                keep(res)
        return res

    @staticmethod
    def _check_faults(res: Any, path: Path) -> None:
        """End the experiment (:class:`SegmentFault`) when a fault ended the recording of
        ``path``; fail the point when one latched during it otherwise.

        The loop went to the safe state during that recording: the file, closed after the
        fault's cycle, is kept and listed (nothing recorded is lost), but the point is not
        what was asked for and must never read as ``done``.
        """
        if getattr(res, "fault", None):
            raise SegmentFault(res.fault, path.name)
        faults = getattr(res, "faults", None) or []
        if faults:
            names = ", ".join(sorted({str(f.get("name", f.get("code"))) for f in faults}))
            raise PointFailed(f"fault {names} latched during {path.name} (file kept; the "
                              "valves went to the safe state: reset the fault, lower the "
                              "excitation and re-run)")

    def discard_partial(self) -> None:
        """Remove the half-recorded file of an interrupted segment."""
        if self._part is not None:
            try:
                self._part.unlink()
            except FileNotFoundError:
                pass
            self._part = None

    # -- K∞ state -----------------------------------------------------------------------
    def controller(self, on: bool) -> None:
        """Switch K∞ (bumpless blend) and let the blend finish, unrecorded, before recording."""
        if controller_enabled(self.loop) == on:
            return
        self.loop.enable_controller(on)
        ramp = getattr(getattr(getattr(self.loop, "config", None), "loop", None), "k_ramp_s",
                       0.05)
        play(self.loop, np.zeros((max(1, _n(2 * ramp + 0.02, self.fs)), 2)))

    def _meta(self, spec: Any, point: dict[str, Any], **extra: Any) -> dict[str, Any]:
        m = dict(self.base_meta)
        m.update({"kind": spec.kind, "omega_rpm": point["omega_rpm"],
                  "p_inj_bar": point["p_inj_bar"], "point": point["index"]})
        m.update(extra)
        return m

    def _n_frames(self, res: Any, default: int) -> int:
        n = getattr(res, "n_frames", None)
        return int(n) if n is not None else default

    def run(self, spec: Any, point: dict[str, Any], stem: str) -> bool:
        """Record ``point``; False when a stop request ended it before all its records."""
        rd = self.manifest.run_dir
        if isinstance(spec, ImpactSpec):
            return self._impact(spec, point, stem)
        if isinstance(spec, RunoutSpec):
            omega = point["omega_rpm"]
            if not omega or omega <= 0:
                raise PointFailed("runout needs a turning shaft (omega_rpm > 0)")
            n = _n(spec.duration_s(omega), self.fs)
            exc = np.zeros((n, 2))
            ctrl = spec.controller
            extra = {"revolutions": spec.revolutions, "controller_on": ctrl}
        else:
            exc = excitation(spec, self.fs)
            ctrl = spec.controller
            extra = {"signal": spec.model_dump_json(exclude={"operating_point", "name",
                                                             "description"}),
                     "lead_in_samples": _n(spec.lead_in_s, self.fs), "controller_on": ctrl}
        path = rd / f"{stem}_{spec.kind}.h5"
        self.controller(ctrl)
        res = self._record(path, self._meta(spec, point, **extra), exc, controller_on=None,
                           keep=lambda res: self.manifest.add_file(
                               point, path, kind=spec.kind, omega_rpm=point["omega_rpm"],
                               p_inj_bar=point["p_inj_bar"], controller_on=ctrl,
                               n_frames=self._n_frames(res, len(exc))))
        self._check_faults(res, path)
        self.tick(f"{spec.kind} point {point['index']}")
        return True

    # -- impacts ---------------------------------------------------------------------------
    def _impact(self, spec: ImpactSpec, point: dict[str, Any], stem: str) -> bool:
        rd = self.manifest.run_dir
        n_pre, n_post = _n(spec.pre_s, self.fs), _n(spec.post_s, self.fs)
        plant = sim_plant(self.loop) if spec.trigger == "sim" else None
        if spec.trigger == "sim" and plant is None:
            raise PointFailed("trigger 'sim' needs the simulated plant's hammer; on a real rig "
                              "use trigger: operator")
        for ctrl in spec.controller:
            self.controller(ctrl)
            for r in range(spec.repeats):
                if self.should_stop():
                    return False
                if spec.spacing_s > 0:  # let the previous response decay, unrecorded
                    play(self.loop, np.zeros((_n(spec.spacing_s, self.fs), 2)))
                path = rd / f"{stem}_impact_{spec.axis}_k{int(ctrl)}_r{r}.h5"
                meta = self._meta(spec, point, axis=spec.axis, controller_on=ctrl, repeat=r,
                                  pre_s=spec.pre_s, post_s=spec.post_s,
                                  trigger_index=n_pre, trigger=spec.trigger)
                if spec.trigger == "sim":
                    meta.update(peak_n=spec.peak_n, pulse_s=spec.pulse_s)
                    hit = Hit(plant, spec.axis, spec.peak_n, spec.pulse_s)

                def keep(n, ctrl=ctrl, r=r, path=path):
                    self.manifest.add_file(point, path, kind="impact",
                                           omega_rpm=point["omega_rpm"],
                                           p_inj_bar=point["p_inj_bar"], controller_on=ctrl,
                                           repeat=r, axis=spec.axis, n_frames=n,
                                           trigger_index=n_pre)

                if spec.trigger == "sim":
                    res = self._record(path, meta, np.zeros((n_pre + n_post, 2)),
                                       controller_on=None, events=[(n_pre, hit)],
                                       keep=lambda res: keep(self._n_frames(res,
                                                                            n_pre + n_post)))
                else:
                    n, res = self._operator_hit(spec, path, meta, ctrl, n_pre, n_post)
                    keep(n)
                self._check_faults(res, path)
                self.tick(f"impact k={'on' if ctrl else 'off'} #{r + 1}")
        return True

    def _operator_hit(self, spec: ImpactSpec, path: Path, meta: dict[str, Any], ctrl: bool,
                      n_pre: int, n_post: int) -> tuple[int, Any]:
        """Record up to ``timeout_s`` while the operator hits; keep the window around the
        first sample where |f_axis| >= trigger_n. Returns (frames kept, the wait's result);
        a fault that ended the wait keeps the whole wait recording."""
        from concurrent.futures.process import BrokenProcessPool

        from rigd.spawn import run as spawned

        tmp = path.with_name(path.name + ".wait")
        n_wait = _n(spec.timeout_s, self.fs)
        try:
            res = self._record(tmp, meta, np.zeros((n_wait, 2)), controller_on=None)
            if getattr(res, "fault", None):
                # a fault ended the wait: keep all of it as the point's record (the caller
                # lists it, then ends the experiment)
                os.replace(tmp, path)
                return self._n_frames(res, n_wait), res
        finally:
            self.discard_partial()
        try:
            # read, cut and written in a helper process: no HDF5 in the loop's process
            n = spawned("rigd.experiments.window", "cut_hit_window", str(tmp), str(path),
                        spec.axis, float(spec.trigger_n), float(spec.timeout_s), n_pre,
                        n_post, meta, timeout_s=600.0)
            return int(n), res
        except (BrokenProcessPool, TimeoutError) as exc:
            how = "ended" if isinstance(exc, BrokenProcessPool) else "did not answer in 600 s"
            raise PointFailed(f"the impact window could not be cut from {tmp.name}: its "
                              f"helper process {how}") from None
        finally:
            tmp.unlink(missing_ok=True)
