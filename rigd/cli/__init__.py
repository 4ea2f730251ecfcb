"""The ``rigd`` command line.

Each sub-command lives in its own module ``rigd/cli/<name>.py`` exposing::

    HELP = "one line"
    def add_arguments(parser: argparse.ArgumentParser) -> None: ...
    def run(args: argparse.Namespace) -> int: ...

and is registered once in :data:`COMMANDS`. A command parses its arguments, calls
:mod:`rigd.api` and prints; commands never import each other (shared argument helpers are in
``rigd/cli/_args.py``). Any :class:`rigd.errors.InputError` escaping a
command becomes one line on stderr and exit status 2 (argparse uses 2 for bad arguments too);
:class:`rigd.errors.DaemonGone` (the daemon ended, a request it never took) exit status 3.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from rigd import __version__
from rigd.errors import InputError

#: command name -> module (imported lazily so `rigd ctl` does not pay for scipy/numba).
COMMANDS: dict[str, str] = {
    "run": "rigd.cli.run",
    "ctl": "rigd.cli.ctl",
    "export": "rigd.cli.export",
    "experiment": "rigd.cli.experiment",
    "identify": "rigd.cli.identify",
    "compare": "rigd.cli.compare",
    "diagnose": "rigd.cli.diagnose",
    "design": "rigd.cli.design",
    "analyze-impact": "rigd.cli.analyze_impact",
    "demo": "rigd.cli.demo",
    "web": "rigd.cli.web",
}


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rigd", description="Rotor-gas bearing rig daemon "
                                     "and modelling workflow.")
    parser.add_argument("--version", action="version", version=f"rigd {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    names = [only] if only in COMMANDS else list(COMMANDS)
    for name in names:
        mod = importlib.import_module(COMMANDS[name])
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # Only import the module of the command asked for (fast `rigd ctl`).
    only = argv[0] if argv and argv[0] in COMMANDS else None
    parser = build_parser(only)
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except InputError as exc:
        print(f"rigd {args.command}: {exc}", file=sys.stderr)
        return int(getattr(exc, "exit_status", 2))
    except KeyboardInterrupt:
        print(f"rigd {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        if _stdout_closed():
            return 0       # `rigd ctl status | head`: the reader had enough
        # any other pipe (a socket, a child's stdin) is a failure, never a silent exit 0
        print(f"rigd {args.command}: broken pipe (the other end closed the connection)",
              file=sys.stderr)
        return 2


def _stdout_closed() -> bool:
    """Did the broken pipe come from stdout — is its reader gone (``POLLERR``/``POLLHUP`` on
    the descriptor)? If so, stdout is pointed at /dev/null so the interpreter's exit flush
    stays quiet."""
    import os
    import select

    try:
        fd = sys.stdout.fileno()
        p = select.poll()
        p.register(fd, select.POLLOUT)
        gone = any(ev & (select.POLLERR | select.POLLHUP) for _, ev in p.poll(0))
    except (OSError, ValueError):    # no descriptor (captured, closed): not a pipe's reader
        return False
    if gone:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
    return gone

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
