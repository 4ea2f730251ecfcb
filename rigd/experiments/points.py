"""One experiment at one operating point: plays it on the loop and writes its record(s).

Records are written to ``<name>.h5.part`` by the loop's recorder (the manifest names it in
the point's ``recording`` while it is written) and renamed to ``<name>.h5`` once closed. A
record cut short — a fault, a full disk, SIGINT, the loop's process ended, an internal error
— is kept all the same: renamed, listed with ``complete: false``, its reason and the frames
on disk (:meth:`PointRunner.keep_partial`). Nothing here deletes a record.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigd.errors import FaultError, InputError
from rigd.experiments import signals
from rigd.experiments.schemas import (
    MAX_RECORD_S,
    ChirpSpec,
    ImpactSpec,
    MultilevelSpec,
    MultisineSpec,
    PrbsSpec,
    RunoutSpec,
)
from rigd.fileio import rename_new
from rigd.loop.writer_link import RecordingFailed
from rigd.owner import holders


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


class LoopEnded(RuntimeError):
    """The loop's process (the daemon) ended while the experiment talked to it."""


class RecordFault(FaultError):
    """A recording failed (disk full, its writer died): the loop latched
    ``recorder_overflow``; the record is kept as far as it was flushed."""

    def __init__(self, text: str, fault: dict[str, Any] | None = None):
        self.fault = dict(fault) if fault and fault.get("code") else \
            {"seq": None, "code": None, "name": "recorder_overflow", "text": text}
        at = f" at cycle {self.fault['seq']}" if self.fault.get("seq") is not None else ""
        super().__init__(f"{self.fault['name']} latched{at}: {text}")


#: longest wait for the writer to let go of a cut-short record before it is marked, s (the
#: daemon's writer closes its files at once when the daemon dies)
RELEASE_WAIT_S = 30.0



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
        #: (part, final path, point, listing info) of the record being written, or None
        self._pending: tuple[Path, Path, dict[str, Any] | None, dict[str, Any]] | None = None

    # -- recording with .part + rename ----------------------------------------------------
    def _record(self, path: Path, meta: dict[str, Any], exc: np.ndarray, *, controller_on: bool,
                events=(), point: dict[str, Any] | None = None,
                info: dict[str, Any] | None = None, n_default: int | None = None) -> Any:
        """Record ``exc`` into ``path`` (via ``.part``), listed in ``point`` with ``info``.

        The ``.part`` is named in the point's ``recording`` (the manifest is the journal a
        recovery reads). The rename and the listing run inside ``critical()`` (the stop
        flag's ``deferring``: a SIGINT there only sets the flag). A recording that failed
        (disk full) is kept as far as it was flushed and ends the experiment
        (:class:`RecordFault`); any other end is the caller's :meth:`keep_partial`.
        """
        from rigd.loop.sinks import RecordSpec

        part = path.with_name(path.name + ".part")
        self._pending = (part, path, point, dict(info or {}))
        if point is not None:
            point["recording"] = part.name
            self.manifest.write()
        try:
            res = self.loop.run_segment(exc, record=RecordSpec(str(part), meta),
                                        events=list(events), controller_on=controller_on,
                                        stop_on_fault=True)
        except RecordingFailed as err:
            self.keep_partial(str(err), err.n_flushed)
            try:
                fault = (self.loop.status() or {}).get("fault")
            except Exception:  # noqa: BLE001 - the fault is named either way
                fault = None
            if err.n_flushed is None and not (fault or {}).get("code"):
                raise PointFailed(str(err)) from None     # refused before it began
            raise RecordFault(str(err), fault) from None
        with self.critical():
            rename_new(part, path)
            self._pending = None
            if point is not None:
                point["recording"] = None
                n = self._n_frames(res, n_default if n_default is not None else len(exc))
                cut = _cut_short(res, path)
                self.manifest.add_file(point, path, **(info or {}), n_frames=n,
                                       **({"complete": False, "incomplete_reason": cut}
                                          if cut else {}))
        return res

    def keep_partial(self, why: str, n_frames: int | None = None) -> None:
        """Keep the record being written when the experiment ended (never deleted): renamed
        to its final name, listed ``complete: false`` with ``why`` and its frames on disk
        (read, and the file marked, in a helper process once its writer let go of it)."""
        pending, self._pending = self._pending, None
        if pending is None:
            return
        part, path, point, info = pending
        if not part.exists():            # never created (cut before the open, or refused):
            if point is not None and point.get("recording"):
                point["recording"] = None    # the manifest names no file that is not there
                self.manifest.write()
            return
        end = time.monotonic() + RELEASE_WAIT_S
        while holders(part) and time.monotonic() < end:
            time.sleep(0.05)
        try:
            rename_new(part, path)
        except FileExistsError:
            path = part                  # a file of that name appeared: keep both as they are
        got = _spawned_info(path, why, marking=not holders(path))
        if got.get("n_frames") is not None:
            n_frames = got["n_frames"]
        entry = {**info, "n_frames": n_frames, "complete": False, "incomplete_reason": why}
        if got.get("readable") is False:
            entry["readable"] = False
        if point is None:
            point = self.manifest.points[int(info.get("point", 0))] if self.manifest.points \
                else {"index": None, "files": []}
        point["recording"] = None
        entry.pop("point", None)
        self.manifest.add_file(point, path, **entry)
        self.manifest.write()

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
            check_record_length(spec.duration_s(omega), "revolutions",
                                f"{spec.revolutions} revolutions at {omega:g} rpm")
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
                           point=point, info={"kind": spec.kind,
                                              "omega_rpm": point["omega_rpm"],
                                              "p_inj_bar": point["p_inj_bar"],
                                              "controller_on": ctrl})
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

                info = {"kind": "impact", "omega_rpm": point["omega_rpm"],
                        "p_inj_bar": point["p_inj_bar"], "controller_on": ctrl, "repeat": r,
                        "axis": spec.axis, "trigger_index": n_pre}
                if spec.trigger == "sim":
                    res = self._record(path, meta, np.zeros((n_pre + n_post, 2)),
                                       controller_on=None, events=[(n_pre, hit)],
                                       point=point, info=info)
                else:
                    n, res, kept = self._operator_hit(spec, point, path, meta, n_pre, n_post,
                                                      info)
                    self.manifest.add_file(point, kept, **info, n_frames=n)
                self._check_faults(res, path)
                self.tick(f"impact k={'on' if ctrl else 'off'} #{r + 1}")
        return True

    def _operator_hit(self, spec: ImpactSpec, point: dict[str, Any], path: Path,
                      meta: dict[str, Any], n_pre: int, n_post: int,
                      info: dict[str, Any]) -> tuple[int, Any, Path]:
        """Record up to ``timeout_s`` while the operator hits; keep the window around the
        first sample where |f_axis| >= trigger_n. Returns (frames kept, the wait's result,
        the file kept): the window, cut in a helper process (the wait, now redundant, is
        then removed); the whole wait when a fault ended it. A wait with no usable hit is
        kept and listed (``impact_wait``) and the point fails."""
        from concurrent.futures.process import BrokenProcessPool

        from rigd.spawn import run as spawned

        tmp = path.with_name(path.name + ".wait")
        n_wait = _n(spec.timeout_s, self.fs)
        wait_info = {**info, "kind": "impact_wait", "point": point["index"]}
        res = self._record(tmp, meta, np.zeros((n_wait, 2)), controller_on=None,
                           info=wait_info)
        if getattr(res, "fault", None):
            # a fault ended the wait: keep all of it as the point's record (the caller
            # lists it, then ends the experiment)
            rename_new(tmp, path)
            return self._n_frames(res, n_wait), res, path
        try:
            # read, cut and written in a helper process: no HDF5 in the loop's process
            n = spawned("rigd.experiments.window", "cut_hit_window", str(tmp), str(path),
                        spec.axis, float(spec.trigger_n), float(spec.timeout_s), n_pre,
                        n_post, meta, timeout_s=600.0)
        except (BrokenProcessPool, TimeoutError, PointFailed) as exc:
            why = (str(exc) if isinstance(exc, PointFailed) else
                   f"the impact window could not be cut from {tmp.name}: its helper process "
                   + ("ended" if isinstance(exc, BrokenProcessPool)
                      else "did not answer in 600 s"))
            kept = path.with_name(path.stem + "_wait.h5")
            try:
                rename_new(tmp, kept)
            except FileExistsError:
                kept = tmp
            wait_info.pop("point")
            self.manifest.add_file(point, kept, **wait_info,
                                   n_frames=self._n_frames(res, n_wait))
            raise PointFailed(f"{why} (the wait is kept: {kept.name})") from None
        tmp.unlink()        # the window holds the hit: the wait around it is not kept
        return int(n), res, path


def check_record_length(seconds: float, key: str, what: str) -> None:
    """InputError naming ``key`` when one record would last over :data:`MAX_RECORD_S`."""
    if not seconds <= MAX_RECORD_S:
        raise InputError(f"{what} last {seconds:.4g} s: over the limit of {MAX_RECORD_S:g} s "
                         f"per record", key)


def _cut_short(res: Any, path: Path) -> str | None:
    """Why the record of ``res`` is shorter than asked (a fault ended it), or None."""
    f = getattr(res, "fault", None)
    if f:
        return f"{f.get('name')} latched at cycle {f.get('seq')}: the segment ended there"
    return None


def _spawned_info(path: Path, why: str, marking: bool) -> dict[str, Any]:
    """:func:`rigd.recording.incomplete.mark_incomplete` (or only ``describe`` when another
    process still holds the file) of ``path``, in a helper process; {} if that failed."""
    from rigd.spawn import run as spawned

    try:
        if marking:
            return spawned("rigd.recording.incomplete", "mark_incomplete", str(path), why,
                           timeout_s=120.0)
        return spawned("rigd.recording.incomplete", "describe", str(path), timeout_s=120.0)
    except Exception:  # noqa: BLE001 - the record stays, listed without its frame count
        return {}
