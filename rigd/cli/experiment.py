"""``rigd experiment FILE.yaml``: run an experiment, via the daemon or in-process.

    rigd experiment config/experiments/prbs.yaml --lockstep --out runs/prbs-1
    rigd experiment config/experiments/sweep.yaml --config config/sim.yaml

With a daemon up on the control socket (and no ``--lockstep``), the experiment runs inside
the daemon (``experiment.start``) and this command follows its progress; otherwise it builds a
loop in-process from ``--config`` (lock-step on the simulated plant with ``--lockstep``).
A progress bar on a terminal, structured log lines otherwise. Ctrl-C stops after the current
segment: completed points are kept and the missing ones listed (exit status 130).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from pathlib import Path

from rigd.errors import InputError

HELP = "run an experiment YAML (PRBS, multisine, chirp, multilevel, runout, impact, sweep)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="experiment YAML (see config/experiments/)")
    p.add_argument("--config", help="rig configuration YAML (default: config/sim.yaml if "
                   "present, else the built-in simulated rig)")
    p.add_argument("--lockstep", action="store_true", help="run in-process, lock-step (as fast "
                   "as possible) on the simulated plant; never uses the daemon")
    p.add_argument("--out", metavar="RUN_DIR", help="new run directory (default: "
                   "runs/<time>-<name>)")
    p.add_argument("--runs-root", default="runs", help="where default run directories go")
    p.add_argument("--socket", help="daemon control socket (default /run/rigd/rigd.sock)")


def _progress_sink(total_hint: str):
    """(callback, close) for progress: tqdm on a terminal, log lines otherwise."""
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=1, desc=total_hint, unit="seg", file=sys.stderr, leave=True)

        def cb(done: int, total: int, text: str) -> None:
            bar.total = total
            bar.n = done
            bar.set_postfix_str(text, refresh=True)

        return cb, bar.close
    from rigd.log import get_logger

    log = get_logger("rigd.experiment")

    def cb(done: int, total: int, text: str) -> None:
        log.info("experiment.progress", done=done, total=total, segment=text)

    return cb, lambda: None


def _confirm(message: str) -> bool:
    if not sys.stdin.isatty():
        return False
    ans = input(f"rigd experiment: {message} [y/N] ")
    return ans.strip().lower() in ("y", "yes")


def _daemon(socket_path: str | None):
    from rigd.service.client import DEFAULT_SOCKET, ControlClient

    path = socket_path or DEFAULT_SOCKET
    if not os.path.exists(path):
        if socket_path:
            raise InputError("no daemon socket here (is rigd running?)", path)
        return None
    client = ControlClient(path, timeout=10.0)
    try:
        client.connect()
        client.call("ping")
    except Exception:
        client.close()
        if socket_path:
            raise
        return None
    return client


def run(args: argparse.Namespace) -> int:
    from rigd.experiments.runner import load

    exp = load(args.file)  # validate first: bad YAML -> one line, exit 2, nothing created
    if not args.lockstep:
        client = _daemon(args.socket)
        if client is not None:
            return _via_daemon(client, args)
    return _in_process(exp, args)


def _config(args):
    from rigd.rigconfig import default_config, load_config

    if args.config:
        return load_config(args.config)
    if Path("config/sim.yaml").exists():
        return load_config("config/sim.yaml")
    return default_config()


class _SigintStop(threading.Event):
    """The stop flag of an in-process run, set by SIGINT (Ctrl-C).

    SIGINT still raises KeyboardInterrupt, which ends the run at once in the usual case. A
    KeyboardInterrupt can however be swallowed when the signal lands inside a finaliser
    (``__del__``, a weakref callback — Python prints "Exception ignored" and carries on), and
    the sweep would then run to its end. The flag makes the runner stop at its next check
    (between segments) even then: the result is "interrupted", exit 130, either way.
    """

    reason = "interrupted by SIGINT"

    def __enter__(self):
        self._old = None
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)

    def _on_sigint(self, signum, frame):
        self.set()
        raise KeyboardInterrupt


def _in_process(exp, args) -> int:
    from rigd.experiments.runner import run_experiment
    from rigd.loop.app import build_loop

    lc = _config(args)
    loop = build_loop(lc, clock="lockstep" if args.lockstep else None)
    cb, close = _progress_sink(exp.name)
    from rigd.log import get_logger

    log = None if sys.stderr.isatty() else get_logger("rigd.experiment")
    stop = _SigintStop()
    try:
        with loop, stop:
            man = run_experiment(exp, loop, args.out, cb, runs_root=args.runs_root,
                                 config_path=getattr(lc, "path", None),
                                 config_text=getattr(lc, "text", None), confirm=_confirm,
                                 log=log, stop=stop)
    finally:
        close()
    return _report(man.status, man.message, str(man.path))


def _report(status: str, message: str, manifest: str) -> int:
    if status == "complete":
        print(f"complete: {message}; manifest: {manifest}")
        return 0
    print(f"rigd experiment: {status}: {message}; manifest: {manifest}", file=sys.stderr)
    return 130 if status == "interrupted" else 1


def _via_daemon(client, args) -> int:
    path = str(Path(args.file).resolve())
    run_dir = str(Path(args.out).resolve()) if args.out else None
    from rigd.service.client import ControlError

    try:
        started = client.call("experiment.start", path=path, **({"run_dir": run_dir}
                                                                  if run_dir else {}))
    except ControlError as exc:
        raise InputError(str(exc), "daemon") from None
    cb, close = _progress_sink(started.get("name") or "experiment")
    st: dict = {}
    try:
        while True:
            try:
                st = client.call("experiment.status")
                if st.get("total"):
                    cb(st.get("done", 0), st["total"], st.get("last", ""))
                if st.get("state") not in ("starting", "running"):
                    break
                time.sleep(0.2)
            except KeyboardInterrupt:
                client.call("experiment.stop")
                print("rigd experiment: stopping after the current segment ...",
                      file=sys.stderr)
    finally:
        close()
        client.close()
    manifest = st.get("manifest") or (str(Path(st["run_dir"]) / "manifest.json")
                                      if st.get("run_dir") else "?")
    return _report(st.get("state", "failed"), st.get("message", ""), manifest)
