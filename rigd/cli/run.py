"""``rigd run``: the control loop on the configured drivers, real time or lock-step.

Parses the arguments, configures logging, builds the loop from the config, runs it for
``--duration`` seconds (or until SIGINT/SIGTERM or a service ``stop``) and prints the timing
statistics. The run is wrapped in :class:`rigd.service.daemon.Daemon` (control socket,
sd_notify, signals). A ``--record`` file says its ``source`` (simulated or rig) and drivers.

``--record`` never overwrites: a file that exists is refused (exit 2, untouched); a folder
(``DIR/``) or a name pattern with ``{start}`` (the start time, UTC) makes a new file at each
start, so a restart keeps the record of what went wrong.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
from pathlib import Path

from rigd.cli._args import print_json

HELP = "run the 5 kHz control loop (simulated plant by default), print timing statistics"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", default="config/sim.yaml", help="rig config YAML "
                   "(default: %(default)s)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="run this many seconds of loop time (default: until stopped; "
                        "0: only build and check)")
    p.add_argument("--lockstep", action="store_true",
                   help="virtual clock: run as fast as the CPU allows")
    p.add_argument("--record", metavar="FILE.h5|DIR/|PATTERN",
                   help="record every frame to a NEW HDF5 file: FILE.h5 (refused if it "
                        "exists), a folder DIR/ (DIR/rigd-<start>.h5) or a pattern with "
                        "{start} (e.g. 'crash-{start}.h5'); start = UTC time of this start")
    p.add_argument("--controller", metavar="FILE", help="K∞ controller YAML to load")
    p.add_argument("--enable-controller", action="store_true",
                   help="enable the loaded K∞ at start (bumpless ramp)")
    p.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])
    p.add_argument("--json", action="store_true", help="print the timing statistics as JSON")
    from rigd.service import daemon

    daemon.add_arguments(p)


def run(args: argparse.Namespace) -> int:
    from rigd import log
    from rigd.errors import InputError
    from rigd.loop.app import build_loop
    from rigd.loop.timing import format_summary
    from rigd.rigconfig import load_config

    log.configure(args.log_level)
    logger = log.get_logger("rigd.run")
    if args.record:
        args.record = str(record_path(args.record))
    if args.duration is not None and args.duration < 0:
        raise InputError(f"must be >= 0 (got {args.duration})", "--duration")
    if args.enable_controller and not args.controller:
        lc0 = load_config(args.config)
        if lc0.config.controller is None:
            raise InputError("needs --controller or a controller: key in the config",
                             "--enable-controller")
    lc = load_config(args.config)
    if args.duration != 0 and not getattr(args, "no_notify", False):
        from rigd.service.notify import extend_start_up

        extend_start_up()   # a cold numba cache compiles for tens of seconds (systemd)
    loop = build_loop(lc, clock="lockstep" if args.lockstep else None,
                      controller=args.controller)
    if args.duration == 0:
        loop.close()
        print(f"{args.config}: configuration OK ({loop.clock} clock, fast driver "
              f"{lc.config.drivers.fast.name!r})")
        return 0
    from rigd.driver import data_source
    from rigd.loop.sinks import RecordSpec
    from rigd.service.daemon import Daemon

    service = Daemon(loop, lc, args)
    sink = None
    status = 0
    with loop:
        if args.record:
            from rigd.loop.recorder import RecordingFailed

            try:
                sink = loop.start_recording(RecordSpec(args.record,
                                                       data_source(loop.fast, loop.slow)))
            except RecordingFailed as exc:   # e.g. a folder it may not write: one line
                raise InputError(str(exc)) from None
        if args.enable_controller:
            loop.enable_controller(True)
        logger.info("loop running", clock=loop.clock, fs_hz=loop.fs, config=args.config,
                    duration_s=args.duration, record=args.record)
        with service:
            try:
                if loop.clock == "lockstep":
                    if args.duration is None:
                        while not loop.stopped:
                            loop.run_cycles(loop.config.clock.batch_cycles)
                    else:
                        loop.run_for(args.duration)
                else:
                    loop.start()
                    loop.wait(args.duration)
            except Exception:
                if loop.loop_error is None:
                    raise       # not the loop's death (that is reported below)
        if sink is not None:
            try:
                loop.stop_recording(sink)
            except Exception as exc:  # e.g. disk full: already a latched fault, logged
                from rigd.loop.recorder import RecordingFailed

                first = str(exc).splitlines()[0]
                # RecordingFailed already names the file, the reason and what it keeps
                failed = (first if isinstance(exc, RecordingFailed)
                          else f"recording {args.record} incomplete: {first}")
                print(f"rigd run: {failed}", file=sys.stderr)
                status = 1
    if loop.loop_error is not None:
        # outputs were set safe when it died; a non-zero exit makes systemd restart us
        print(f"rigd run: the loop died ({loop.loop_error!r}); outputs were set safe",
              file=sys.stderr)
        status = 3
    timing = loop.timing()
    faults = loop.faults()
    if args.json:
        print_json({"timing": timing, "faults": faults}, indent=2)
    else:
        print(format_summary(timing))
        for f in faults:
            print(f"fault at cycle {f['seq']}: {f['name']} ({f['text']})")
        if sink is not None:
            print(f"recorded {frames_on_disk(sink)} frames to {args.record}")
    return status


#: the start time in ``--record`` names (UTC, sortable, no ':' for other filesystems)
START_FORMAT = "%Y%m%dT%H%M%SZ"


def record_path(arg: str, now: _dt.datetime | None = None) -> Path:
    """The new file ``--record ARG`` writes (see module docstring).

    Raises
    ------
    InputError
        The file exists, the pattern has another ``{...}`` field, or the name holds a
        control character.
    """
    from rigd.errors import InputError

    now = now or _dt.datetime.now(_dt.timezone.utc)
    start = now.strftime(START_FORMAT)
    if any(ord(c) < 32 or ord(c) == 127 for c in arg):
        raise InputError("the name holds a control character", "--record")
    if "{" in arg or "}" in arg:
        try:
            name = arg.format(start=start)
        except (KeyError, IndexError, ValueError):
            raise InputError(f"{arg!r}: the only field of a pattern is {{start}}",
                             "--record") from None
        return _free(Path(name))
    p = Path(arg)
    if arg.endswith(os.sep) or p.is_dir():
        return _free(p / f"rigd-{start}.h5")
    if os.path.lexists(p):
        raise InputError(f"{arg} exists: a record is never overwritten (give a new name, a "
                         "folder DIR/ or a pattern with {start})", "--record")
    return p


def _free(p: Path) -> Path:
    """``p``, or ``p`` with ``-2``, ``-3``... before its suffix when taken (two starts in one
    second)."""
    if not os.path.lexists(p):
        return p
    for i in range(2, 10000):
        q = p.with_name(f"{p.stem}-{i}{p.suffix}")
        if not os.path.lexists(q):
            return q
    return p          # pragma: no cover - the writer then refuses it (mode "x")


def frames_on_disk(sink) -> int:
    """Frames of ``sink``'s file on disk: all written when it closed, else (a failed
    recording) those of its last flush."""
    return int(sink.n_flushed if sink.error is not None else sink.n_written)
