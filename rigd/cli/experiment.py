"""``rigd experiment FILE.yaml``: run an experiment, via the daemon or in-process.

    rigd experiment config/experiments/prbs.yaml --lockstep --out runs/prbs-1
    rigd experiment config/experiments/sweep.yaml --config config/sim.yaml

Where it runs is the caller's choice, never a fall-back:

* ``--lockstep`` and/or ``--config CONFIG``: in this process, on a loop built from CONFIG
  (default ``config/sim.yaml`` if present, else the built-in simulated rig), lock-step with
  ``--lockstep``, else on the real-time clock;
* otherwise inside the daemon on the control socket (``--socket``, ``$RIGD_SOCKET`` or
  ``/run/rigd/rigd.sock``): ``experiment.start``, then its progress is followed. A socket that
  is missing or does not answer ``ping`` within ``--timeout`` is one line and exit 2; nothing
  runs elsewhere instead.

Records and ``manifest.json`` say ``source: simulated | rig`` and the driver names. A progress
bar on a terminal, structured log lines otherwise. Ctrl-C stops after the current segment:
completed points are kept and the missing ones listed (exit status 130). The work is
:func:`rigd.api.run_experiment` / :func:`rigd.api.run_experiment_daemon`.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading

from rigd.errors import InputError

HELP = "run an experiment YAML (PRBS, multisine, chirp, multilevel, runout, impact, sweep)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="experiment YAML (see config/experiments/)")
    p.add_argument("--config", help="run in-process on this rig configuration YAML (real-time "
                   "clock unless --lockstep); never uses the daemon")
    p.add_argument("--lockstep", action="store_true", help="run in-process, lock-step (as fast "
                   "as possible), on --config or else config/sim.yaml if present, else the "
                   "built-in simulated rig; never uses the daemon")
    p.add_argument("--out", metavar="RUN_DIR", help="new run directory (default: "
                   "runs/<time>-<name>)")
    p.add_argument("--runs-root", default="runs", help="where default run directories go")
    p.add_argument("--socket", help="daemon control socket (default $RIGD_SOCKET, else "
                   "/run/rigd/rigd.sock)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="seconds to wait for the daemon's reply (default 10)")


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


def run(args: argparse.Namespace) -> int:
    from rigd.experiments.runner import load

    exp = load(args.file)  # validate first: bad YAML -> one line, exit 2, nothing created
    if args.lockstep or args.config:
        if args.socket:
            raise InputError("--socket runs the experiment in the daemon, --lockstep/--config "
                             "in this process: give one or the other", "--socket")
        return _in_process(exp, args)
    if not args.timeout > 0:
        raise InputError(f"must be > 0 (got {args.timeout})", "--timeout")
    return _via_daemon(args, exp.name)


class _SigintStop(threading.Event):
    """The stop flag of an in-process run, set by SIGINT (Ctrl-C).

    SIGINT still raises KeyboardInterrupt, which ends the run at once in the usual case. Not
    when the signal lands inside a finaliser (``__del__``, a weakref callback): there Python
    would print "Exception ignored … Traceback" to the operator and drop it (seen once in a
    test run). The flag makes the runner stop at its next check (between segments): the
    result is "interrupted", exit 130, either way.

    Inside :meth:`deferring` (a finished record being renamed into place and listed in the
    manifest) SIGINT only sets the flag: the runner stops at its next check, right after, with
    that record kept and listed — never a complete file on disk that the manifest does not
    name.
    """

    reason = "interrupted by SIGINT"

    def __enter__(self):
        self._old = None
        self._defer = 0
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)

    @contextlib.contextmanager
    def deferring(self):
        """SIGINT sets the flag but raises nothing inside this block."""
        self._defer = getattr(self, "_defer", 0) + 1
        try:
            yield
        finally:
            self._defer -= 1

    def _on_sigint(self, signum, frame):
        self.set()
        if not getattr(self, "_defer", 0) and not _in_finaliser(frame):
            raise KeyboardInterrupt


#: code that runs as a finaliser (garbage collection): an exception raised there is printed as
#: "Exception ignored in … Traceback" and dropped
_FINALISER_FILES = ("weakref.py", "_weakrefset.py")


def _in_finaliser(frame) -> bool:
    """Did the signal land in a finaliser (``__del__``, a weakref callback)? There
    KeyboardInterrupt would only print a traceback to the operator and be dropped; the flag
    alone stops the run at the runner's next check."""
    if frame is None:
        return False
    code = frame.f_code
    return code.co_name == "__del__" or code.co_filename.endswith(_FINALISER_FILES)


def recover_stale(runs_root: str) -> list[dict]:
    """Recover the runs under ``runs_root`` a dead process left ``running`` (as the daemon
    does on start; HDF5 read in a helper process), one line each on stderr."""
    from rigd.owner import stale_runs
    from rigd.spawn import run as spawned

    if not stale_runs(runs_root):
        return []
    got = spawned("rigd.experiments.recovery", "recover_runs", str(runs_root),
                  timeout_s=300.0)
    for r in got:
        said = r.get("skipped") or f"{r['status']}: {r.get('message', '')}"
        print(f"rigd experiment: recovered {r['run_dir']}: {said}", file=sys.stderr)
    return got


def _in_process(exp, args) -> int:
    from rigd.api.experiment import run_experiment
    from rigd.log import get_logger

    recover_stale(args.runs_root)

    cb, close = _progress_sink(exp.name)
    log = None if sys.stderr.isatty() else get_logger("rigd.experiment")
    stop = _SigintStop()
    try:
        with stop:
            res = run_experiment(exp, config=args.config, lockstep=args.lockstep, out=args.out,
                                 runs_root=args.runs_root, progress=cb, stop=stop,
                                 confirm=_confirm, log=log)
    finally:
        close()
    return _report(res.status, res.message, res.manifest)


def _report(status: str, message: str, manifest: str) -> int:
    if status == "complete":
        print(f"complete: {message}; manifest: {manifest}")
        return 0
    print(f"rigd experiment: {status}: {message}; manifest: {manifest}", file=sys.stderr)
    return 130 if status == "interrupted" else 1


def _via_daemon(args, name: str) -> int:
    from rigd.api.experiment import connect_daemon, run_experiment_daemon

    client = connect_daemon(args.socket, timeout=args.timeout)
    cb, close = _progress_sink(name or "experiment")

    def stopping() -> None:
        print("rigd experiment: stopping after the current segment ...", file=sys.stderr)

    try:
        res = run_experiment_daemon(args.file, client=client, out=args.out, progress=cb,
                                    on_stop=stopping)
    finally:
        close()
    return _report(res.status, res.message, res.manifest)
