"""Experiments from the daemon: each in an experiment process of its own.

The daemon's ``experiment.start`` / ``experiment.status`` / ``experiment.stop`` map to
:meth:`ExperimentHost.start`, :meth:`status` and :meth:`stop`. The experiment's bookkeeping
(spec, excitation signals, run folder, manifests, renames) runs in a process spawned by module
name (:mod:`rigd.experiments.process`; import contract: this module and the rest of the
loop's process never import :mod:`rigd.experiments`); here one thread per experiment only
answers its small, packed calls on the loop (docs/ARCHITECTURE.md, "The loop's process"):

* a segment: the excitation's samples come in a sealed memfd, mapped read-only and copied
  once by ``run_segment`` (into the padded array it plays); a hammer blow as
  ``("impact", axis, peak_n, pulse_s)``, called on the loop's simulated plant at its cycle;
* ``status``, ``enable``, ``op`` (K∞ on/off, the operating point).

On start, runs a dead process left ``running`` are recovered in a helper process
(:mod:`rigd.experiments.recovery`): their records kept and listed incomplete, their state
``interrupted (process ended)``; ``status`` lists them under ``recovered``.

Whatever the experiment process does, the state ends in ``complete``, ``interrupted`` or
``failed`` (with a message): a process that ends without its final word, or that has said
nothing :data:`START_LIMIT_S` after its spawn (killed then), gives ``failed`` naming how.

A SAFE stops the experiment that was running when the cycle took it: the daemon sees the SAFE
late (its service thread polls), so :meth:`ExperimentHost.stop` is given the SAFE's number
(the loop's ``safe_generation``) and leaves alone an experiment started after that SAFE —
one started after the fault's reset, before the late stop arrived, was found ``interrupted``
at once ("stopped on request; 0 of 1 point(s) done"; tests/web/test_web_process.py hung
waiting for it to complete).
"""

from __future__ import annotations

import contextlib
import json
import mmap
import multiprocessing
import os
import threading
import time
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

from rigd.bounded import confined
from rigd.driver import data_source
from rigd.errors import FaultError, InputError
from rigd.loop.writer_link import RecordingFailed, how_ended
from rigd.owner import stale_runs
from rigd.spawn import call
from rigd.spawn import run as call_in_helper

#: how long ``start`` waits for the experiment process to make its run folder, s (the spawn
#: and its imports take seconds on a loaded machine; a spec refused in it answers sooner)
START_WAIT_S = 60.0

#: longest silence of a new experiment process before its first word, s: then it is killed
#: and the experiment failed, saying so. Only a hung start reaches it: the spawn and its
#: imports (numpy, pydantic, the experiments' code) took 7 s at load 8 on the shared
#: 2-core machine, "tens of seconds" at load 25
START_LIMIT_S = 120.0

#: longest the recovery of dead runs on start may take, s (a helper process reading HDF5)
RECOVERY_LIMIT_S = 300.0

#: the experiment process's entry point, by module name (tests point it elsewhere)
ENTRY = ("rigd.experiments.process", "main")


def _plant(loop: Any) -> Any | None:
    """The loop's simulated plant with a hammer (``impact``), or None."""
    for name in ("fast", "plant", "driver", "fast_driver"):
        d = getattr(loop, name, None)
        if d is not None and callable(getattr(d, "impact", None)):
            return d
    return None


class ExperimentHost:
    """Runs experiments on ``loop``, each in an experiment process; thread-safe
    ``start``/``status``/``stop``.

    Parameters
    ----------
    loop : rigd.loop.ControlLoop
    runs_root : path
        Where run directories go when a request gives no ``run_dir``.
    log : structlog logger, optional
    """

    def __init__(self, loop: Any, runs_root: str | Path = "runs", log: Any = None):
        self.loop = loop
        self.runs_root = Path(runs_root)
        self.log = log
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._proc: Any = None
        #: the running experiment's stop event and the SAFE generation it started in
        self._run: tuple[Any, int | None] = (None, None)
        self.entry = ENTRY
        self.start_limit_s = START_LIMIT_S
        self._state: dict[str, Any] = {"state": "idle"}
        #: set once the running experiment's process said it is done (or ended)
        self._over = threading.Event()
        self._over.set()
        #: runs a dead process left ``running``, recovered on start (in a helper process)
        self.recovered: list[dict[str, Any]] = []
        self._recovery: threading.Thread | None = None
        if stale_runs(self.runs_root):
            self._recovery = threading.Thread(target=self._recover, name="rigd-recovery",
                                              daemon=True)
            self._recovery.start()

    def _recover(self) -> None:
        """Recover the runs a dead process left ``running`` (:mod:`rigd.experiments.recovery`,
        run by module name in a helper: it reads HDF5); said in ``status`` and the log."""
        try:
            got = call_in_helper("rigd.experiments.recovery", "recover_runs",
                                 str(self.runs_root), timeout_s=RECOVERY_LIMIT_S)
        except Exception as exc:  # noqa: BLE001 - the daemon runs on; said in the log
            got = [{"run_dir": str(self.runs_root), "status": "running",
                    "skipped": f"recovery failed: {type(exc).__name__}: {exc}"}]
        self.recovered = got
        if self._state.get("state") == "idle":
            self._state = {"state": "idle", "recovered": got}
        for r in got:
            if self.log is not None:
                (self.log.warning if r.get("skipped") else self.log.info)(
                    "experiment run recovered" if not r.get("skipped")
                    else "experiment run not recovered", **r)

    def _recover_lost(self, proc: Any) -> None:
        """The experiment process ended (killed) and left its run ``running``: recover that
        run at once (its record kept and listed incomplete, state ``interrupted (process
        ended)``), as the next start would."""
        rd = self._state.get("run_dir")
        if self._state.get("state") != "failed" or not rd or proc.is_alive():
            return
        try:                      # cheap: JSON only; the recovery reads HDF5 in a helper
            if json.loads((Path(rd) / "manifest.json").read_text()).get("status") != "running":
                return
        except (OSError, ValueError):
            return
        try:
            got = call_in_helper("rigd.experiments.recovery", "recover_run", str(rd),
                                 timeout_s=RECOVERY_LIMIT_S)
        except Exception as exc:  # noqa: BLE001 - the next start tries again
            if self.log is not None:
                self.log.error("experiment run not recovered", run_dir=rd, error=repr(exc))
            return
        if not got.get("skipped"):
            self._state.update(state=got["status"],
                               message=f"{self._state.get('message')}; {got['message']}")
            if self.log is not None:
                self.log.info("experiment run recovered", **got)

    def wait_recovered(self, timeout: float = RECOVERY_LIMIT_S) -> None:
        """Block until the start's recovery (if any) is over."""
        t = self._recovery
        if t is not None:
            t.join(timeout)

    def _facts(self) -> dict[str, Any]:
        """What the runner reads of the loop (fixed while it runs)."""
        loop = self.loop
        fs = getattr(loop, "fs", None) or (loop.status() or {}).get("fs_hz")
        loaded = getattr(loop, "loaded", None)
        cfg = getattr(getattr(loop, "config", None), "loop", None)
        fast = getattr(loop, "fast", None)
        return {"fs_hz": float(fs), "clock": str(getattr(loop, "clock", "unknown")),
                "k_ramp_s": float(getattr(cfg, "k_ramp_s", 0.05)),
                "config_path": getattr(loaded, "path", None),
                "config_text": getattr(loaded, "text", None),
                "source_info": (data_source(fast, getattr(loop, "slow", ()))
                                if fast is not None else None),
                "hammer": _plant(loop) is not None}

    def start(self, path: str | None = None, spec: dict | None = None,
              run_dir: str | None = None, experiment: dict | None = None) -> dict[str, Any]:
        """Start an experiment; ``{"run_dir", "name", "kind", "total"}`` once its run folder
        exists.

        Parameters
        ----------
        path, spec : str, dict
            The experiment YAML or an inline spec (read and validated in the experiment
            process), or
        experiment : dict
            one already read, validated and packed by the socket process
            (:func:`rigd.service.reader.read_experiment`).
        run_dir : str, optional
            Must lie inside the runs folder (symlinks resolved).

        Raises
        ------
        InputError
            Another experiment is running, the run folder is outside the runs folder, or the
            spec is invalid.
        """
        if run_dir is not None:
            run_dir = str(confined(run_dir, self.runs_root, "experiment.start: run_dir"))
        request = ({"packed": experiment} if experiment is not None
                   else {"spec": spec} if spec is not None else {"path": path})
        self.wait_recovered()
        with self._lock:
            if not self._over.is_set():
                raise InputError("an experiment is already running (experiment.stop first)",
                                 "experiment.start")
            ctx = multiprocessing.get_context("spawn")
            ours, theirs = ctx.Pipe()
            gen = getattr(self.loop, "safe_generation", None)
            stop = ctx.Event()
            self._run = (stop, gen if isinstance(gen, int) else None)
            started = threading.Event()
            self._over = over = threading.Event()
            packed = experiment or {}
            self._state = {"state": "starting", "name": packed.get("name"),
                           "kind": packed.get("kind"), "done": 0, "total": None,
                           "run_dir": None, "message": ""}
            # not daemonic: an operator impact's window is cut in a helper it spawns
            self._proc = ctx.Process(target=call, name="rigd-experiment", args=(
                *self.entry, theirs, stop, request, run_dir, str(self.runs_root),
                self._facts()))
            self._proc.start()
            self._state["pid"] = self._proc.pid
            theirs.close()
            self._thread = threading.Thread(target=self._serve,
                                            args=(ours, self._proc, started, over),
                                            name="rigd-experiment", daemon=True)
            self._thread.start()
        started.wait(START_WAIT_S)
        if self._state["state"] == "failed":
            raise InputError(self._state["message"], "experiment.start")
        return {k: self._state.get(k) for k in ("run_dir", "name", "kind", "total")}

    def status(self) -> dict[str, Any]:
        """State of the current/last experiment (``idle``, ``starting``, ``running``,
        ``complete``, ``interrupted``, ``interrupted (process ended)``, ``failed``) with
        ``done``/``total`` segments, the run directory and ``pid`` (its experiment process);
        ``fault`` (seq, code, name, text) when a latched fault ended it; ``recovered``
        (while idle after a start): the runs a dead process had left ``running``."""
        return dict(self._state)

    def stop(self, before_safe: int | None = None) -> dict[str, Any]:
        """Ask the running experiment to stop after the current segment.

        Parameters
        ----------
        before_safe : int, optional
            A SAFE's stop, however late it comes: the loop's ``safe_generation`` once the
            cycle took that SAFE. Only an experiment started before it is stopped.
        """
        running = not self._over.is_set()
        ev, gen = self._run          # one tuple: never one experiment's event with another's
        if before_safe is not None and gen is not None and gen >= before_safe:
            return {"stopping": False}          # started after that SAFE
        if ev is not None:
            ev.set()
        return {"stopping": running}

    @property
    def pid(self) -> int | None:
        """The current (or last) experiment process's pid, or None."""
        return getattr(self._proc, "pid", None)

    def join(self, timeout: float | None = None) -> None:
        """Wait up to ``timeout`` for the experiment to be over (tests, shutdown); its process
        is then given a few seconds to exit, and killed if it has not (or if the experiment is
        not over by then: a process left behind would hold the daemon's exit)."""
        over = self._over.wait(timeout)
        proc = self._proc
        if proc is not None:
            proc.join(10.0 if over else 0.0)
            if proc.is_alive():
                proc.kill()
                proc.join(5.0)

    # --- the experiment's thread: answers its process's calls -------------------------
    def _fail(self, why: str) -> None:
        """End a state still ``starting``/``running`` in ``failed`` with ``why``."""
        if self._state.get("state") in ("starting", "running"):
            self._state.update(state="failed", message=why)
            if self.log is not None:
                self.log.error("experiment failed", reason=why)

    def _next(self, conn: Any, proc: Any, heard: bool, t0: float) -> Any:
        """The process's next message; None when it ended or (before its first word) was
        killed at :attr:`start_limit_s` — the state is then ``failed`` with the reason."""
        while True:
            left = None if heard else self.start_limit_s - (time.monotonic() - t0)
            if left is not None and left <= 0:
                proc.kill()
                proc.join(5.0)
                self._fail(f"the experiment process said nothing within "
                           f"{self.start_limit_s:g} s of its start; killed")
                return None
            if not wait([conn, proc.sentinel], left):
                continue
            try:
                if conn.poll():       # what it sent before it ended is read first
                    return conn.recv()
            except (EOFError, OSError):
                pass
            proc.join(5.0)
            self._fail(f"the experiment process ended without its result "
                       f"({how_ended(proc.exitcode)})")
            return None

    def _serve(self, conn: Any, proc: Any, started: threading.Event,
               over: threading.Event) -> None:
        t0 = time.monotonic()
        heard = False
        try:
            while True:
                msg = self._next(conn, proc, heard, t0)
                if msg is None:
                    return
                heard = True
                kind = msg[0]
                if kind == "state":
                    self._state.update(msg[1])
                    if msg[1].get("state") == "running":
                        started.set()
                elif kind == "done":
                    self._state.update(msg[1])
                    return
                elif kind == "call":
                    answer = self._answer(conn, msg[1], msg[2:], proc)
                    try:
                        conn.send(answer)
                    except OSError:           # it died while its call ran (a segment)
                        proc.join(5.0)
                        self._fail(f"the experiment process ended during its "
                                   f"{msg[1]} call ({how_ended(proc.exitcode)})")
                        return
        except Exception as exc:  # noqa: BLE001 - a bug here must not leave it "running"
            proc.kill()
            self._fail(f"internal error serving the experiment process: {exc!r}")
        finally:
            self._fail("the experiment process ended without its result")  # if still open
            proc.join(5.0)            # reaped (it exits after its last word)
            self._recover_lost(proc)
            over.set()
            started.set()
            conn.close()

    def _answer(self, conn: Any, name: str, args: tuple, proc: Any = None) -> tuple:
        try:
            if name == "segment":
                with self._owner_watched(proc):
                    return ("ok", self._segment(conn, *args))
            if name == "status":
                return ("ok", self.loop.status())
            if name == "enable":
                self.loop.enable_controller(bool(args[0]))
                return ("ok", None)
            if name == "op":
                self.loop.set_operating_point(float(args[0]), float(args[1]))
                return ("ok", None)
            return ("raise", "internal", f"unknown call {name!r}")
        except InputError as exc:
            return ("raise", "input", str(exc))
        except RecordingFailed as exc:        # disk full, the writer died: what it kept
            return ("raise", "recording", str(exc), exc.n_flushed)
        except FaultError as exc:
            return ("raise", "fault", str(exc))
        except Exception as exc:  # noqa: BLE001 - the experiment fails, the daemon lives
            return ("raise", "internal", f"{type(exc).__name__}: {exc}")

    @contextlib.contextmanager
    def _owner_watched(self, proc: Any):
        """While a segment plays for ``proc``: if that process ends, the segment is cancelled
        at the next cycle (nobody is left to want its excitation; its record is kept as far
        as it was played), instead of playing on to its planned end."""
        if proc is None:
            yield
            return
        over = threading.Event()

        def watch() -> None:
            while not over.is_set() and not wait([proc.sentinel], 0.1):
                pass
            # it ended: cancel the segment as soon as it plays (the call may still be on its
            # way to the loop: the file being created, not yet offered) until the call is over
            while not over.is_set():
                if self.loop.cancel_segment("the experiment process ended"):
                    if self.log is not None:
                        self.log.warning("experiment segment cancelled",
                                         reason="the experiment process ended")
                    return
                over.wait(0.01)

        t = threading.Thread(target=watch, name="rigd-segment-owner", daemon=True)
        t.start()
        try:
            yield
        finally:
            over.set()
            t.join(1.0)

    def _segment(self, conn: Any, n: int, record: Any, events: list, controller_on: Any,
                 stop_on_fault: bool, pre: int, post: int) -> dict[str, Any]:
        from multiprocessing.reduction import recv_handle

        import numpy as np

        fd = recv_handle(conn)
        try:
            size = max(int(n) * 16, 1)
            if os.fstat(fd).st_size < size:
                raise InputError(f"segment of {n} samples: its shared memory is too small")
            with mmap.mmap(fd, size, flags=mmap.MAP_SHARED, prot=mmap.PROT_READ) as mm:
                exc = np.ndarray((int(n), 2), dtype=np.float64, buffer=mm)
                try:
                    res = self.loop.run_segment(
                        exc, record=self._record(record), events=self._events(events),
                        controller_on=controller_on, stop_on_fault=stop_on_fault, pre=pre,
                        post=post)
                finally:
                    del exc
        finally:
            os.close(fd)
        return {k: getattr(res, k, None) for k in ("first_seq", "last_seq", "n_frames", "path",
                                                   "frames", "faults", "fault")}

    @staticmethod
    def _record(record: Any) -> Any:
        from rigd.loop.sinks import RecordSpec

        if record is None or record == "memory":
            return record
        _, path, meta = record
        return RecordSpec(str(path), dict(meta))

    def _events(self, events: list) -> list:
        plant = _plant(self.loop)
        out = []
        for off, (what, axis, peak_n, pulse_s) in events:
            if what != "impact" or plant is None:
                raise InputError(f"event {what!r} at {off}: no simulated hammer on this loop")
            out.append((int(off), lambda a=str(axis), f=float(peak_n), d=float(pulse_s):
                        plant.impact(a, f, d)))
        return out


__all__ = ["ExperimentHost"]
