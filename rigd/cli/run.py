"""``rigd run``: the control loop on the configured drivers, real time or lock-step.

Parses the arguments, configures logging, builds the loop from the config, runs it for
``--duration`` seconds (or until SIGINT/SIGTERM or a service ``stop``) and prints the timing
statistics. The run is wrapped in :class:`rigd.service.daemon.Daemon` (control socket,
sd_notify, signals). A ``--record`` file says its ``source`` (simulated or rig) and drivers.
"""

from __future__ import annotations

import argparse
import sys

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
    p.add_argument("--record", metavar="FILE.h5", help="record every frame to this HDF5 file")
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
            print(f"recorded {sink.n_written} frames to {args.record}")
    return status
