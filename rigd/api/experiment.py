"""run_experiment: an experiment YAML played in-process (lock-step or real time) or by the daemon.

In-process runs build a loop from a rig configuration (the simulated plant by default); a run
through the daemon sends ``experiment.start`` over the control socket and follows
``experiment.status``. A socket that does not answer is an error, never a reason to run
somewhere else: the caller chooses in-process or daemon explicitly.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rigd.errors import InputError

#: progress(done, total, text): called after each recorded segment.
Progress = Callable[[int, int, str], None]

#: How to run in-process instead of through the daemon (said when the socket does not answer).
IN_PROCESS_HINT = "nothing was run; start rigd, or run in-process with --lockstep or --config"


@dataclass
class ExperimentResult:
    """The outcome of one experiment run.

    Attributes
    ----------
    status : {"complete", "interrupted", "failed"}
    message : str
        Points done and missing, or why it failed.
    manifest : str
        Path of the run's ``manifest.json`` (``"?"`` if the daemon did not say).
    mode : {"lockstep", "realtime", "daemon"}
        Where it ran.
    """

    status: str
    message: str
    manifest: str
    mode: str

    @property
    def ok(self) -> bool:
        return self.status == "complete"

    @property
    def run_dir(self) -> Path:
        return Path(self.manifest).parent

    def read_manifest(self) -> dict[str, Any]:
        """The run's manifest (records, points, ``source`` and driver names)."""
        from rigd.data.manifest import read_manifest

        return read_manifest(self.manifest)


def default_config():
    """``config/sim.yaml`` if present in the working directory, else the built-in sim rig."""
    from rigd.rigconfig import default_config as builtin
    from rigd.rigconfig import load_config

    if Path("config/sim.yaml").exists():
        return load_config("config/sim.yaml")
    return builtin()


def run_experiment(spec: Any, *, config: Any = None, lockstep: bool = True,
                   out: str | Path | None = None, runs_root: str | Path = "runs",
                   controller: str | Path | None = None, progress: Progress | None = None,
                   stop: threading.Event | None = None,
                   confirm: Callable[[str], bool] | None = None,
                   log: Any = None) -> ExperimentResult:
    """Run an experiment in this process on a loop built from a rig configuration.

    Parameters
    ----------
    spec : path, dict or rigd.experiments.runner.Experiment
        Experiment YAML (``config/experiments/*.yaml``) or the same as a dict, e.g.
        ``{"kind": "prbs", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4},
        "amplitude_v": 1.0, "duration_s": 2.0}`` (amplitudes in V, durations in s).
    config : path or LoadedConfig, optional
        Rig configuration (default :func:`default_config`: the simulated plant).
    lockstep : bool
        Virtual clock: run as fast as the CPU allows (True, default) or in real time.
    out : path, optional
        New, empty run directory (default ``runs_root/<UTC time>-<name>``).
    controller : path, optional
        K∞ controller file to load (default: the config's ``controller:`` key).
    progress : callable(done, total, text), optional
    stop : threading.Event, optional
        Set it to stop after the current segment (completed points are kept).
    confirm : callable(message) -> bool, optional
        Asks the operator (``set_point_by: operator`` sweeps).
    log : structlog logger, optional

    Returns
    -------
    ExperimentResult
        Status, message and the manifest path; records are HDF5 files in the run directory,
        their metadata and the manifest say ``source: simulated | rig`` and the drivers.
    """
    from rigd.experiments.runner import run_experiment as _run
    from rigd.loop.app import build_loop
    from rigd.rigconfig import LoadedConfig, load_config

    if config is None:
        lc = default_config()
    elif isinstance(config, LoadedConfig):
        lc = config
    else:
        lc = load_config(config)
    loop = build_loop(lc, clock="lockstep" if lockstep else None, controller=controller)
    with loop:
        man = _run(spec, loop, out, progress, runs_root=runs_root,
                   config_path=getattr(lc, "path", None), config_text=getattr(lc, "text", None),
                   confirm=confirm, log=log, stop=stop)
    return ExperimentResult(man.status, man.message, str(man.path),
                            "lockstep" if lockstep else "realtime")


def connect_daemon(socket: str | None = None, *, timeout: float = 10.0):
    """A connected :class:`~rigd.service.client.ControlClient` whose daemon answered ``ping``.

    Parameters
    ----------
    socket : str, optional
        Control socket (default ``$RIGD_SOCKET``, else ``/run/rigd/rigd.sock``).
    timeout : float
        Seconds to wait for the daemon's reply.

    Raises
    ------
    InputError
        No socket file, nobody listening, permission denied, no reply within ``timeout``,
        or a refused ping: one line naming the socket. Nothing is run elsewhere instead.
    """
    from rigd.service.client import DEFAULT_SOCKET, ControlClient, ControlError

    path = socket or os.environ.get("RIGD_SOCKET") or DEFAULT_SOCKET
    if not os.path.exists(path):
        raise InputError(f"no daemon socket here (is rigd running?); {IN_PROCESS_HINT}", path)
    client = ControlClient(path, timeout=timeout)
    try:
        client.connect()
        client.call("ping")
    except InputError as exc:
        client.close()
        raise InputError(f"daemon does not answer: {exc.message}; {IN_PROCESS_HINT}",
                         path) from None
    except (ControlError, OSError, ValueError) as exc:
        client.close()
        raise InputError(f"daemon does not answer ping: {exc}; {IN_PROCESS_HINT}",
                         path) from None
    return client


def run_experiment_daemon(spec: str | Path, *, socket: str | None = None, client: Any = None,
                          out: str | Path | None = None, progress: Progress | None = None,
                          timeout: float = 10.0, poll_s: float = 0.2,
                          on_stop: Callable[[], None] | None = None) -> ExperimentResult:
    """Run an experiment YAML inside the running daemon and follow it to its end.

    Parameters
    ----------
    spec : path
        Experiment YAML (validated here first, then read by the daemon).
    socket : str, optional
        Control socket (see :func:`connect_daemon`); or pass a connected ``client``.
    out : path, optional
        Run directory (default: the daemon's runs folder).
    progress : callable(done, total, text), optional
    on_stop : callable, optional
        Called when a KeyboardInterrupt asked the daemon to stop after the current segment.

    Returns
    -------
    ExperimentResult
        ``mode`` is ``"daemon"``.
    """
    from rigd.experiments.runner import load
    from rigd.service.client import ControlError, experiment_args

    load(str(spec))  # a bad file: one line here, the daemon never sees it
    if client is None:
        client = connect_daemon(socket, timeout=timeout)
    path = str(Path(spec).resolve())
    run_dir = str(Path(out).resolve()) if out else None
    st: dict[str, Any] = {}
    try:
        try:
            # the file's text goes with its name: the daemon opens no file a client names
            client.call("experiment.start", **experiment_args(path),
                        **({"run_dir": run_dir} if run_dir else {}))
        except ControlError as exc:
            raise InputError(str(exc), "daemon") from None
        while True:
            try:
                st = client.call("experiment.status")
                if progress and st.get("total"):
                    progress(st.get("done", 0), st["total"], st.get("last", ""))
                if st.get("state") not in ("starting", "running"):
                    break
                time.sleep(poll_s)
            except KeyboardInterrupt:
                client.call("experiment.stop")
                if on_stop:
                    on_stop()
    finally:
        client.close()
    manifest = st.get("manifest") or (str(Path(st["run_dir"]) / "manifest.json")
                                      if st.get("run_dir") else "?")
    return ExperimentResult(st.get("state", "failed"), st.get("message", ""), manifest,
                            "daemon")


__all__ = ["ExperimentResult", "connect_daemon", "default_config", "run_experiment",
           "run_experiment_daemon"]
