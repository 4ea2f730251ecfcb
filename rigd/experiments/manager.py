"""Experiments inside the daemon: one at a time, in a background thread.

The control-socket server maps ``experiment.start`` / ``experiment.status`` /
``experiment.stop`` to :meth:`ExperimentManager.start`, :meth:`status` and :meth:`stop`.
Requests are validated before anything runs (a bad spec is an error reply, nothing starts).
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from rigd.bounded import confined
from rigd.errors import InputError
from rigd.experiments.manifest import Manifest
from rigd.experiments.runner import Experiment, load, run_experiment


class ExperimentManager:
    """Runs experiments on ``loop`` in a thread; thread-safe ``start``/``status``/``stop``.

    Parameters
    ----------
    loop : rigd.loop.ControlLoop
    runs_root : path
        Where run directories go when a request gives no ``run_dir``.
    """

    def __init__(self, loop: Any, runs_root: str | Path = "runs", log: Any = None):
        self.loop = loop
        self.runs_root = Path(runs_root)
        self.log = log
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._state: dict[str, Any] = {"state": "idle"}
        self._manifest: Manifest | None = None

    def start(self, path: str | None = None, spec: dict | None = None,
              run_dir: str | None = None, experiment: Experiment | dict | None = None
              ) -> dict[str, Any]:
        """Validate and start an experiment; returns ``{"run_dir", "name", "kind", "total"}``.

        Parameters
        ----------
        path, spec : str, dict
            The experiment YAML or an inline spec (read and validated here), or
        experiment : rigd.experiments.runner.Experiment or dict
            one already read and validated (by the daemon's socket process: nothing is read
            or parsed in the loop's process); a dict holds its fields (spec, point, source,
            text: :func:`rigd.service.reader.read_experiment`).
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
        with self._lock:
            if self._thread is not None and self._thread.is_alive():
                raise InputError("an experiment is already running (experiment.stop first)",
                                 "experiment.start")
            if isinstance(experiment, dict):
                experiment = Experiment(**experiment)
            exp = experiment if experiment is not None else load(
                spec if spec is not None else path)
            self._stop.clear()
            started = threading.Event()
            self._state = {"state": "starting", "name": exp.name, "kind": exp.spec.kind,
                           "done": 0, "total": None, "run_dir": None, "message": ""}

            def progress(done: int, total: int, text: str) -> None:
                self._state.update(done=done, total=total, last=text)

            def on_start(man: Manifest) -> None:
                self._manifest = man
                self._state.update(state="running", run_dir=str(man.run_dir),
                                   manifest=str(man.path))
                started.set()

            def work() -> None:
                try:
                    man = run_experiment(exp, self.loop, run_dir, progress,
                                         runs_root=self.runs_root, stop=self._stop,
                                         log=self.log, on_start=on_start)
                    self._state.update(state=man.status, message=man.message,
                                       missing=man.missing, fault=man.fault)
                except InputError as exc:
                    self._state.update(state="failed", message=str(exc))
                except Exception as exc:  # noqa: BLE001 - reported through status
                    self._state.update(state="failed", message=f"internal error: {exc!r}")
                finally:
                    started.set()

            self._thread = threading.Thread(target=work, name="rigd-experiment", daemon=True)
            self._thread.start()
        started.wait(30.0)
        if self._state["state"] == "failed":
            raise InputError(self._state["message"], "experiment.start")
        return {k: self._state.get(k) for k in ("run_dir", "name", "kind", "total")}

    def status(self) -> dict[str, Any]:
        """State of the current/last experiment (``idle``, ``running``, ``complete``,
        ``interrupted``, ``failed``) with ``done``/``total`` segments and the run directory;
        ``fault`` (seq, code, name, text) when a latched fault ended it."""
        return dict(self._state)

    def stop(self) -> dict[str, Any]:
        """Ask the running experiment to stop after the current segment."""
        running = self._thread is not None and self._thread.is_alive()
        self._stop.set()
        return {"stopping": running}

    def join(self, timeout: float | None = None) -> None:
        """Wait for the experiment thread (tests, shutdown)."""
        if self._thread is not None:
            self._thread.join(timeout)
