"""Run an experiment on a :class:`rigd.loop.ControlLoop`: :func:`run_experiment`.

Used in-process by ``rigd experiment`` and inside the daemon (``experiment.start`` on the
control socket). Every run gets a NEW run directory with its records and ``manifest.json``
(:mod:`rigd.experiments.manifest`); the manifest is rewritten after each operating point and
before each record, so an interrupted run (Ctrl-C / SIGINT, ``stop``, a fault, a full disk,
the daemon's end) keeps every completed point, lists the missing ones, and keeps the record
it was writing, marked incomplete. A run whose own process was killed is recovered by the
next start (:mod:`rigd.experiments.recovery`).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigd.driver import data_source
from rigd.errors import FaultError, InputError
from rigd.experiments.manifest import Manifest, new_run_dir, now_iso, sha256_text
from rigd.experiments.points import (
    LoopEnded,
    PointFailed,
    PointRunner,
    check_against_rate,
    check_record_length,
    controller_enabled,
    controller_loaded,
    loop_fs,
    segments,
    wants_controller,
)
from rigd.experiments.schemas import SettleSpec, SweepSpec, load_experiment, spec_from_dict
from rigd.experiments.sweep import set_point, settle_check
from rigd.owner import PROCESS_ENDED

#: progress(done, total, text): called after each recorded segment.
Progress = Callable[[int, int, str], None]


@dataclass
class Experiment:
    """A validated experiment: the spec, the per-point spec of a sweep, where it came from."""

    spec: Any
    point: Any = None
    source: str = "<spec>"
    text: str | None = None
    #: SHA-256 of the spec's text when the text itself did not travel (a packed experiment)
    sha256: str | None = None

    @property
    def name(self) -> str:
        if self.spec.name:
            return self.spec.name
        if self.source.startswith("<"):
            return self.spec.kind
        return Path(self.source).stem

    @property
    def point_spec(self) -> Any:
        return self.point if isinstance(self.spec, SweepSpec) else self.spec


def load(spec: Any) -> Experiment:
    """An :class:`Experiment` from a path, an inline dict, or an Experiment."""
    if isinstance(spec, Experiment):
        return spec
    if isinstance(spec, dict):
        s, p = spec_from_dict(spec)
        return Experiment(s, p, "<spec>", None)
    s, p, text = load_experiment(spec)
    return Experiment(s, p, str(spec), text)


def run_experiment(spec: Any, loop: Any, run_dir: str | Path | None, progress: Progress | None
                   = None, *, runs_root: str | Path = "runs", config_path: str | None = None,
                   config_text: str | None = None, stop: threading.Event | None = None,
                   confirm: Callable[[str], bool] | None = None, log: Any = None,
                   on_start: Callable[[Manifest], None] | None = None) -> Manifest:
    """Run an experiment and return its manifest.

    Parameters
    ----------
    spec : path, dict or Experiment
        Experiment YAML file, inline spec, or an already validated :class:`Experiment`.
    loop : rigd.loop.ControlLoop
        A running loop (lock-step or real-time) with ``run_segment`` and
        ``set_operating_point``.
    run_dir : path or None
        New (or empty) directory for this run; None: ``runs_root/<UTC time>-<name>``.
    progress : callable(done, total, text), optional
    config_path, config_text : str, optional
        The rig configuration used (its SHA-256 goes into the manifest).
    stop : threading.Event, optional
        Set it to stop after the current segment (the daemon's ``experiment.stop``).
    confirm : callable(message) -> bool, optional
        Asks the operator (``set_point_by: operator``).
    log : structlog logger, optional
    on_start : callable(manifest), optional
        Called once the run directory and first manifest exist.

    Returns
    -------
    Manifest
        ``status`` is ``complete``, ``interrupted`` (SIGINT or ``stop``; completed points kept,
        the others listed in ``missing``) or ``failed`` (a point failed, or a rig fault: a
        fault latched while a segment played ends the segment at that cycle and the
        experiment at once; ``fault`` and ``message`` name it, the point is ``failed`` with
        its record kept up to the fault).

    Raises
    ------
    InputError
        Invalid spec, a request the loop rate cannot honour, or a fault latched already
        (before anything runs).
    """
    exp = load(spec)
    fs = loop_fs(loop)
    check_against_rate(exp.point_spec, fs, exp.source + (": at_each" if exp.point else ""))
    _check_lengths(exp)
    if wants_controller(exp.point_spec) and controller_loaded(loop) is False:
        raise InputError("K∞ on is requested (controller) but the loop has no controller "
                         "loaded: set 'controller:' in the rig config", exp.source)
    _refuse_latched_fault(loop, exp.source)
    k_was = controller_enabled(loop)
    src = getattr(loop, "source_info", None) or data_source(loop.fast, getattr(loop, "slow", ()))
    rd = new_run_dir(run_dir, exp.name, runs_root)
    cfg_text = config_text
    if cfg_text is None:
        cfg_text = getattr(getattr(loop, "loaded", None), "text", None)
    man = Manifest(
        run_dir=rd,
        experiment={"name": exp.name, "kind": exp.spec.kind, "source": exp.source,
                    "spec": exp.spec.model_dump(mode="json"),
                    "at_each": exp.point.model_dump(mode="json") if exp.point else None,
                    "spec_sha256": sha256_text(exp.text) if exp.text else exp.sha256},
        mode=str(getattr(loop, "clock", "unknown")), fs_hz=fs,
        config={"path": config_path or getattr(getattr(loop, "loaded", None), "path", None),
                "sha256": sha256_text(cfg_text) if cfg_text else None},
        **src)
    if isinstance(exp.spec, SweepSpec):
        ops = exp.spec.points()
    else:
        ops = [exp.spec.operating_point]
    for op in ops:
        man.add_point(op.omega_rpm if op else None, op.p_inj_bar if op else None)
    man.reserve()
    man.write()
    if on_start:
        on_start(man)
    total = len(ops) * segments(exp.point_spec)
    done = [0]

    def tick(text: str) -> None:
        done[0] += 1
        if progress:
            progress(done[0], total, text)

    def should_stop() -> bool:
        return stop is not None and stop.is_set()

    base_meta = {"experiment": exp.name, "run_dir": rd.name, **src}
    runner = PointRunner(loop, man, fs, base_meta, tick, should_stop,
                         critical=getattr(stop, "deferring", None) or contextlib.nullcontext)
    current: dict[str, Any] | None = None
    try:
        for op, pt in zip(ops, man.points):
            if should_stop():
                break
            current = pt
            pt.update(status="running", started=now_iso())
            man.write()
            if log:
                log.info("experiment.point", index=pt["index"], omega_rpm=pt["omega_rpm"],
                         p_inj_bar=pt["p_inj_bar"], kind=exp.point_spec.kind)
            try:
                if op is not None:
                    set_point(loop, op, getattr(exp.spec, "set_point_by", "loop")
                              if isinstance(exp.spec, SweepSpec) else "loop", confirm)
                    settle = (exp.spec.settle if isinstance(exp.spec, SweepSpec)
                              else SettleSpec())
                    pt["settle"] = settle_check(loop, op, settle, fs)
                    if not pt["settle"]["settled"]:
                        raise PointFailed("operating point not reached within "
                                          f"{settle.timeout_s:g} s")
                elif pt["omega_rpm"] is None:
                    last = (loop.status() or {}).get("last_frame", {})
                    pt["omega_rpm"] = _finite(last.get("omega_rpm"))
                    pt["p_inj_bar"] = _finite(last.get("p_inj_bar"))
                stem = f"p{pt['index']:03d}_w{_fmt(pt['omega_rpm'])}_p{_fmt(pt['p_inj_bar'])}"
                complete = runner.run(exp.point_spec, pt, stem)
            except PointFailed as exc:
                pt.update(status="not_settled" if "not reached" in str(exc) else "failed",
                          error=str(exc), finished=now_iso())
                man.write()
                if log:
                    log.warning("experiment.point_failed", index=pt["index"], error=str(exc))
                continue
            if not complete:             # a stop request ended it between its records
                runner.keep_partial("stopped on request")
                break
            # all its records are complete, renamed and listed: done, even when a stop was
            # requested meanwhile (the loop's next check stops before the next point)
            pt.update(status="done", finished=now_iso())
            current = None
            man.write()
    except KeyboardInterrupt:
        runner.keep_partial("interrupted by SIGINT")
        _restore_controller(loop, k_was)
        _finish(man, "interrupted", current, "interrupted by SIGINT")
        return man
    except LoopEnded as exc:
        # the daemon died: its writer closed the record (every frame it had), kept here
        why = f"the daemon (the loop's process) ended during the run: {exc}"
        runner.keep_partial(why)
        if log:
            log.error("experiment.loop_ended", error=str(exc))
        _finish(man, PROCESS_ENDED, current, why)
        return man
    except FaultError as exc:
        # a latched fault ends the experiment at once (the segment ended at its cycle, its
        # record is closed and listed): the point failed, the others are missing
        runner.keep_partial(f"rig fault: {exc}")
        man.fault = getattr(exc, "fault", None)
        if current is not None and current["status"] == "running":
            current.update(status="failed", error=str(exc), finished=now_iso())
        if log:
            log.warning("experiment.fault", error=str(exc))
        _restore_controller(loop, k_was)
        _finish(man, "failed", current, f"rig fault: {exc}")
        return man
    except BaseException as exc:
        why = f"internal error: {type(exc).__name__}: {exc}"
        if log:
            log.exception("experiment.internal_error", error=why)
        runner.keep_partial(why)
        _finish(man, "failed", current, why)
        raise
    _restore_controller(loop, k_was)
    if should_stop():
        _finish(man, "interrupted", current, getattr(stop, "reason", "") or "stopped on request")
    else:
        failed = [p["index"] for p in man.points if p["status"] != "done"]
        _finish(man, "complete" if not failed else "failed", None,
                "" if not failed else f"points {failed} failed")
    return man


def _check_lengths(exp: Experiment) -> None:
    """InputError when a record of ``exp`` would last over the limit (a runout's length
    depends on the speed: checked at every point whose speed is known)."""
    from rigd.experiments.schemas import RunoutSpec

    spec = exp.point_spec
    if not isinstance(spec, RunoutSpec):
        return
    ops = exp.spec.points() if isinstance(exp.spec, SweepSpec) else [exp.spec.operating_point]
    speeds = [op.omega_rpm for op in ops if op is not None and op.omega_rpm > 0]
    if speeds:
        w = min(speeds)
        check_record_length(spec.duration_s(w), f"{exp.source}: revolutions",
                            f"{spec.revolutions} revolutions at {w:g} rpm")


def _refuse_latched_fault(loop: Any, where: str) -> None:
    """InputError while a fault is latched: every segment would end at its first cycle."""
    status = getattr(loop, "status", None)
    fault = (status() or {}).get("fault") or {} if callable(status) else {}
    if fault.get("code"):
        raise InputError(f"fault {fault.get('name')} is latched (cycle {fault.get('seq')}): "
                         "the rig is in the safe state; reset the fault (rigd ctl reset) "
                         "before starting an experiment", where)


def _restore_controller(loop: Any, was: bool | None) -> None:
    """Leave K∞ as we found it."""
    if was is not None and controller_enabled(loop) != was:
        try:
            loop.enable_controller(was)
            loop.run_segment(np.zeros((max(1, int(0.12 * loop_fs(loop))), 2)))  # apply + blend
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass


def _finish(man: Manifest, status: str, current: dict[str, Any] | None, why: str) -> None:
    if current is not None and current["status"] == "running":
        current.update(status="missing", error=why, files=[f for f in current["files"]])
        # files of a partly done point (e.g. some impacts) stay listed and on disk
    for p in man.points:
        if p["status"] == "running":
            p["status"] = "missing"
    man.status = status
    man.finished = now_iso()
    man.release()
    done = sum(p["status"] == "done" for p in man.points)
    miss = man.missing
    man.message = (f"{why}; " if why else "") + (
        f"{done} of {len(man.points)} point(s) done" +
        (f"; missing: {', '.join(_label(man.points[i]) for i in miss)}" if miss else ""))
    man.write()


def _label(p: dict[str, Any]) -> str:
    if p["omega_rpm"] is None:
        return f"#{p['index']}"
    return f"#{p['index']} ({p['omega_rpm']:g} rpm, {p['p_inj_bar']:g} bar)"


def _fmt(v: float | None) -> str:
    if v is None:
        return "na"
    return f"{v:g}".replace(".", "_").replace("-", "m")


def _finite(v: Any) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if f == f and abs(f) != float("inf") else None


__all__ = ["Experiment", "InputError", "Manifest", "load", "run_experiment"]
