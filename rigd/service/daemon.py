"""The daemon around a running loop: control socket, sd_notify, signals, experiments.

``rigd run`` wraps its run in ``with Daemon(loop, config, args): ...``:

* **socket** (``--socket PATH``): served by a spawned socket process
  (:class:`~rigd.service.bridge.SocketFrontend`, :mod:`rigd.service.frontend`) that validates
  every request and answers queries from a snapshot published here; valid commands come back
  to the :class:`~rigd.service.protocol.Dispatcher`, mapping them to the loop and to the
  :class:`~rigd.service.experiment_host.ExperimentHost` (each experiment's bookkeeping runs
  in an experiment process of its own, :mod:`rigd.experiments.process`);
* **sd_notify** (unless ``--no-notify``): ``READY=1`` once the loop cycles, ``STATUS=`` on
  every change (fault latched/reset, experiment), ``WATCHDOG=1`` at half ``WATCHDOG_USEC`` —
  only while the loop's cycle counter advances, so a hung loop gets restarted by systemd —
  and ``STOPPING=1`` on the way out;
* **SIGTERM / SIGINT**: stop the experiment after its segment, trip the loop into the safe
  state (``operator_stop``: K∞ off, excitation off, r_p = r0), let a few cycles record it,
  stop the loop; ``rigd run`` then flushes and closes the recordings and exits 0;
* **SIGUSR1**: SAFE (``operator_safe`` latched by the next cycle) through the loop's SAFE word
  — the same as ``rigd ctl safe``; the handler only writes the word;
* **SIGUSR2**: every thread's stack to stderr (:mod:`faulthandler`), here and in every
  process spawned by module name (:func:`rigd.spawn.call`): where a hang stands;
* **SAFE word** (with ``--socket``): ``<socket>.safe``, the socket's permissions, mapped by
  the loop's cycle (:mod:`rigd.loop.safeword`): ``rigd ctl safe`` and ``rigd web`` write
  their SAFE into it directly — no client slot, no worker thread, nothing to wait behind;
* **SIGHUP**: re-read the config file and the controller, *validated first* — in a spawned
  helper process (:mod:`rigd.service.spawned`, :func:`rigd.service.reader.reload_files`),
  never in this one; a bad file is refused with one log line and the loop keeps running
  untouched; a valid controller comes back packed (its matrices) and is switched bumplessly;
  other config changes are reported as needing a restart (the loop's structure — drivers,
  rate, ring size — is fixed while it runs).

Nothing in this process reads or parses a file a client or a signal names: the socket
process reads ``controller.load``'s and ``experiment.start``'s files, the helper SIGHUP's
(docs/ARCHITECTURE.md, "The loop's process"; import contract in pyproject.toml).

Latched faults: the loop logs each once (structlog); the daemon drains the loop's fault queue
into the systemd status line and ``faults`` answers.
"""

from __future__ import annotations

import argparse
import os
import signal
import threading
import time
from typing import Any

from rigd import __version__
from rigd.errors import InputError
from rigd.log import get_logger
from rigd.service import spawned
from rigd.service.bridge import SocketFrontend, as_helper
from rigd.service.experiment_host import ExperimentHost
from rigd.service.notify import Notifier
from rigd.service.protocol import Dispatcher, unpack_controller
from rigd.spawn import dump_stacks_on_sigusr2

#: the timing statistics in the socket's snapshot are refreshed this often, s
TIMING_REFRESH_S = 0.2
#: after the loop died, the socket keeps answering (``rigd ctl status`` shows ``loop_died``)
#: this long before the daemon exits non-zero for systemd to restart it, s
LOOP_DEATH_LINGER_S = 2.0
#: on SIGTERM/SIGINT/stop, cycles run (and recorded) in the safe state before the loop stops
SAFE_CYCLES_ON_STOP = 20


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Service options of ``rigd run``."""
    g = p.add_argument_group("service")
    g.add_argument("--socket", default=os.environ.get("RIGD_SOCKET"), metavar="PATH",
                   help="control socket for `rigd ctl` (default $RIGD_SOCKET; none if unset; "
                        "the systemd unit uses /run/rigd/rigd.sock)")
    g.add_argument("--socket-mode", default="0660", metavar="OCTAL",
                   help="permissions of the socket file (default %(default)s)")
    g.add_argument("--no-notify", action="store_true",
                   help="do not talk to systemd even if NOTIFY_SOCKET is set")
    g.add_argument("--client-idle-s", type=_positive, default=None, metavar="S",
                   help="close a socket client that completed no request for S seconds "
                        "(default 60; bytes of an unfinished line do not count)")
    g.add_argument("--client-evict-s", type=_nonnegative_or_never, default=None, metavar="S",
                   help="when every client slot is held, close the client idle longest (at "
                        "least S seconds) to make room for a new one (default 0; 'never': "
                        "a full daemon refuses new clients but the few kept for control)")
    g.add_argument("--runs-dir", default="runs", metavar="DIR",
                   help="where experiments started over the socket write their runs")


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"not a positive number of seconds: {text!r}")
    return v


def _nonnegative_or_never(text: str) -> float | str:
    if text == "never":
        return "never"
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not v >= 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"not a number of seconds >= 0 nor 'never': {text!r}")
    return v


class Daemon:
    """Context manager running the service parts around ``loop`` (see module docstring).

    Parameters
    ----------
    loop : rigd.loop.ControlLoop
    config : rigd.rigconfig.LoadedConfig
        The configuration the loop was built from (its path is re-read on SIGHUP).
    args : argparse.Namespace
        ``socket``, ``socket_mode``, ``no_notify``, ``runs_dir``, ``controller`` (optional).
    """

    def __init__(self, loop: Any, config: Any, args: argparse.Namespace):
        self.loop = loop
        self.config = config
        self.args = args
        self.log = get_logger("rigd.service")
        self.notifier = Notifier(environ={} if getattr(args, "no_notify", False) else None)
        self.experiments = None
        self.server: SocketFrontend | None = None
        self.dispatcher: Dispatcher | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._shutdown_started = threading.Lock()
        self._reload_lock = threading.Lock()
        self._old_handlers: dict[int, Any] = {}
        self._faults = None
        self._fault_text = ""
        self._started = time.monotonic()
        self.ready = threading.Event()
        self.last_reload: dict[str, Any] = {"state": "none"}
        self.exit_reason = ""
        self._timing: tuple[float, dict] | None = None
        self._watchdog = None

    # --- life cycle -------------------------------------------------------------------
    def __enter__(self) -> Daemon:
        runs_root = os.path.abspath(getattr(self.args, "runs_dir", None) or "runs")
        self.experiments = ExperimentHost(self.loop, runs_root, log=self.log)
        self.dispatcher = Dispatcher(self.loop, self.experiments, info=self._info,
                                     reads_files=False)
        sock = getattr(self.args, "socket", None)
        if sock:
            try:
                mode = int(str(getattr(self.args, "socket_mode", "0660")), 8)
            except ValueError:
                raise InputError(f"not an octal mode: {self.args.socket_mode!r}",
                                 "--socket-mode") from None
            self.server = SocketFrontend(sock, mode, self.dispatcher.handle_line,
                                         self._snapshot, log=self.log,
                                         helper_priority=self._helper_priority(),
                                         ring=self._ring(),
                                         safe_generation=self._safe_generation,
                                         fs_hz=float(self.loop.fs),
                                         runs_root=runs_root,
                                         gates=self._gates(),
                                         idle_s=getattr(self.args, "client_idle_s",
                                                        None),
                                         evict_s=getattr(self.args, "client_evict_s", None),
                                         word=lambda: self._share_word(sock, mode)).start()
        self._start_watchdog()
        self._faults = self.loop.subscribe()
        if threading.current_thread() is threading.main_thread():
            for s, h in ((signal.SIGTERM, self._on_stop_signal),
                         (signal.SIGINT, self._on_stop_signal),
                         (signal.SIGHUP, self._on_hup),
                         (signal.SIGUSR1, self._on_safe_signal)):
                self._old_handlers[s] = signal.signal(s, h)
            dump_stacks_on_sigusr2()
        self._thread = threading.Thread(target=self._service_run, name="rigd-service",
                                        daemon=True)
        self._thread.start()
        self.log.info("service started", socket=sock, notify=self.notifier.enabled,
                      watchdog_s=self.notifier.watchdog_s)
        return self

    def __exit__(self, *exc) -> None:
        err = getattr(self.loop, "loop_error", None)
        self._quiet_watchdog()   # the run is over (stopped, or died): not a stall
        if err is not None:   # the loop died: say so (STATUS=, the log, the socket), then go
            self.exit_reason = f"loop died: {err!r}"
            self._drain_faults()
            self.notifier.status(self._status_text(-1))
            self.log.error("loop died, daemon exits for a restart", error=repr(err),
                           linger_s=LOOP_DEATH_LINGER_S)
            if self.server is not None:
                self.server.publish_now()
                time.sleep(LOOP_DEATH_LINGER_S)   # the outputs are safe already
        self.notifier.stopping(f"stopping{': ' + self.exit_reason if self.exit_reason else ''}")
        if self.experiments is not None:
            self.experiments.stop()
            self.experiments.join(30.0)  # its recording is finished before the loop closes
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        self._stop_watchdog()
        if self.server is not None:
            self.server.stop()
        safe = getattr(self.loop, "safe", None)
        if safe is not None:
            safe.detach_file()
        for s, h in self._old_handlers.items():
            signal.signal(s, h)
        self._old_handlers.clear()
        self.notifier.close()
        self.log.info("service stopped", reason=self.exit_reason or "end of run")

    def _info(self) -> dict[str, Any]:
        return {"pid": os.getpid(), "version": __version__,
                "uptime_s": round(time.monotonic() - self._started, 3),
                "config": getattr(self.config, "path", None),
                "clients": self.server.n_clients if self.server else 0,
                # requests that reached this (the loop's) process: valid commands only
                "commands_run": (self.dispatcher.served + self.dispatcher.refused
                                 if self.dispatcher else 0),
                "last_reload": dict(self.last_reload)}

    def _ring(self):
        """The recorder's shared ring for the live stream (None for a loop without one)."""
        shared = getattr(getattr(self.loop, "recorder", None), "shared", None)
        if shared is None:
            return None
        if shared.unshared:
            self.log.warning("live stream unavailable (stream.subscribe refused); control and "
                             "recording unaffected", reason=shared.unshared)
        return shared.handle()

    def _share_word(self, sock: str, mode: int):
        """Attach the SAFE word beside the bound socket; its handle for the socket process."""
        self._attach_safe_word(sock, mode)
        safe = getattr(self.loop, "safe", None)
        return safe.handle() if hasattr(safe, "handle") else None

    def _attach_safe_word(self, sock: str, mode: int) -> None:
        """Put the loop's SAFE word in a file beside the socket (before the cycles start)."""
        from rigd.loop.safeword import word_path

        safe = getattr(self.loop, "safe", None)
        if safe is None:
            return
        if getattr(getattr(self.loop, "rt", None), "started", False):
            self.log.warning("SAFE word not shared: the loop was started before the service; "
                             "`safe` goes by the socket")
            return
        try:
            path = safe.attach_file(word_path(sock), mode)
        except OSError as exc:
            self.log.warning("SAFE word not shared; `safe` goes by the socket",
                             error=exc.strerror or str(exc))
            return
        self.log.info("SAFE word shared", path=path)

    def _start_watchdog(self) -> None:
        """Spawn the loop's watchdog process (:mod:`rigd.service.watchdog`) on the SAFE word:
        a real-time loop only (its stall bound is in the word; 0: nothing to watch)."""
        from rigd.loop.safeword import W_STALL_BOUND_NS

        safe = getattr(self.loop, "safe", None)
        if safe is None or not hasattr(safe, "handle") or int(safe.word[W_STALL_BOUND_NS]) <= 0:
            return
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        here, there = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=spawned.call, name="rigd-watchdog", daemon=True,
                           args=("rigd.service.watchdog", "main", safe.handle(), here,
                                 self._helper_priority()))
        proc.start()
        here.close()
        self._watchdog = (proc, there)
        self.log.info("loop watchdog started", pid=proc.pid,
                      **getattr(getattr(self.loop, "liveness", None), "as_dict", dict)())

    def _stop_watchdog(self) -> None:
        self._quiet_watchdog()
        wd, self._watchdog = self._watchdog, None
        if wd is None:
            return
        proc, conn = wd
        conn.close()              # EOF: the watchdog exits
        proc.join(5.0)
        if proc.is_alive():
            proc.kill()
            proc.join(2.0)

    def _quiet_watchdog(self) -> None:
        """The loop is about to stop on purpose: nothing to watch any more (bound 0)."""
        from rigd.loop.safeword import W_STALL_BOUND_NS

        safe = getattr(self.loop, "safe", None)
        if safe is not None and hasattr(safe, "word"):
            safe.word[W_STALL_BOUND_NS] = 0

    def _safe_generation(self) -> int | None:
        gen = getattr(self.loop, "safe_generation", None)
        return gen if isinstance(gen, int) else None

    def _on_safe_signal(self, _signum, _frame) -> None:
        """SIGUSR1: SAFE through the word (two stores; the service thread logs it and stops
        the experiment)."""
        request = getattr(self.loop, "request_safe", None)
        if request is not None:
            request()
        else:
            from rigd.loop import faults as FC

            self.loop.trip(FC.OPERATOR_SAFE)

    def _gates(self) -> dict[str, Any] | None:
        """The config's ``controller_gates`` for the socket process (plain values)."""
        opts = getattr(self.config, "gate_options", None)
        return opts() if opts is not None else None

    def _helper_priority(self) -> int | None:
        """SCHED_FIFO priority for the service's threads on a real-time loop: just below it."""
        if getattr(self.loop, "clock", "") != "realtime":
            return None
        try:
            return max(1, int(self.loop.config.clock.priority) - 1)
        except (AttributeError, TypeError, ValueError):
            return None

    def _snapshot(self) -> dict[str, Any]:
        """What the socket process answers queries from (rigd.service.bridge)."""
        loop = self.loop
        now = time.monotonic()
        if self._timing is None or now - self._timing[0] >= TIMING_REFRESH_S:
            self._timing = (now, loop.timing())   # percentiles of 2 x 20 000 bins: the
                                                  # costly part, so refreshed less often
        return {"status": loop.status(), "timing": self._timing[1],
                "faults": loop.faults(), "info": self._info(),
                "experiment": (self.experiments.status() if self.experiments is not None
                               else None)}

    # --- signals (main thread; hand the work to threads and return at once) -------------
    def _on_stop_signal(self, signum, _frame) -> None:
        name = signal.Signals(signum).name
        if not self._shutdown_started.acquire(blocking=False):
            return  # already stopping
        self.exit_reason = name
        threading.Thread(target=self.shutdown, args=(name,), name="rigd-shutdown",
                         daemon=True).start()

    def shutdown(self, why: str = "request") -> None:
        """Safe outputs, stop the experiment and the loop (any thread)."""
        from rigd.loop import faults as FC

        self.log.info("shutting down", reason=why)
        self.notifier.stopping(f"stopping ({why})")
        if self.experiments is not None:
            self.experiments.stop()
        self.loop.trip(FC.OPERATOR_STOP)           # safe state from the next cycle on
        # let the safe state be applied and recorded: 20 cycles counted (a fixed 4 ms of wall
        # time let only 3 run on a loaded machine); the bound is for a hung loop only, whose
        # close() writes the safe drive anyway
        self.loop.wait_cycles(SAFE_CYCLES_ON_STOP, timeout=5.0)
        self._quiet_watchdog()
        self.loop.stop()

    def _on_hup(self, _signum, _frame) -> None:
        threading.Thread(target=self.reload, name="rigd-reload", daemon=True).start()

    def reload(self) -> dict[str, Any]:
        """Re-read config and controller in a spawned helper process, validated first; the
        packed controller is switched in; never disturbs the loop on error."""
        with self._reload_lock:
            path = getattr(self.config, "path", None)
            try:
                if not path or str(path).startswith("<"):
                    raise InputError("the running config was not read from a file", "SIGHUP")
                kind, res = spawned.run("rigd.service.reader", "reload_files", str(path),
                                        getattr(self.args, "controller", None),
                                        float(self.loop.fs), self._sections())
                if kind != "ok":
                    raise InputError(res)
                ctrl = res["controller"]
                if res["packed"] is not None:   # checked again (cheap), switched bumplessly
                    self.loop.load_controller(unpack_controller(res["packed"]))
                changed = res["needs_restart"]
                self.last_reload = {"state": "applied", "controller": ctrl,
                                    "needs_restart": changed, "time": time.time()}
                self.log.info("reloaded on SIGHUP", controller=ctrl,
                              needs_restart=changed or None)
                note = f" (restart needed for: {', '.join(changed)})" if changed else ""
                self.notifier.status(f"reloaded{note}")
            except InputError as exc:
                self.last_reload = {"state": "refused", "error": str(exc), "time": time.time()}
                self.log.error("reload refused, loop unchanged", error=str(exc))
                self.notifier.status(f"reload refused: {exc}")
            except Exception as exc:  # noqa: BLE001 - never take the daemon down on a reload
                self.last_reload = {"state": "refused", "error": repr(exc), "time": time.time()}
                self.log.error("reload failed, loop unchanged", error=repr(exc))
            if self.server is not None:
                self.server.publish_now()
            return dict(self.last_reload)

    def _sections(self) -> dict[str, Any]:
        """The running config's sections as plain values (compared by the SIGHUP helper)."""
        try:
            return self.config.config.model_dump(mode="json")
        except AttributeError:
            return {}

    # --- the service thread: READY, WATCHDOG, STATUS -----------------------------------
    def _service_run(self) -> None:
        as_helper(self._helper_priority())
        wd = self.notifier.watchdog_interval_s
        tick = min(wd, 0.25) if wd > 0 else 0.25
        last_seq = -1
        last_wd = 0.0
        last_status = ""
        last_gen = self._safe_generation()
        while not self._stop.wait(tick):
            gen = self._safe_generation()
            if gen != last_gen:       # a SAFE taken by the cycle (word, signal, socket)
                last_gen = gen
                self.log.warning("SAFE taken by the loop (operator_safe); experiment stopped, "
                                 "queued commands dropped", safe_requests=gen)
                if self.experiments is not None:
                    # only one started before this SAFE: seen late (this thread polls), a
                    # SAFE must not stop an experiment started after it (after the reset)
                    self.experiments.stop(before_safe=gen)
                if self.server is not None:
                    self.server.publish_now()
            try:
                seq = int(self.loop.status().get("seq", 0))
            except Exception:  # noqa: BLE001
                seq = last_seq
            running = bool(getattr(self.loop, "running", True))
            advancing = seq != last_seq
            last_seq = seq
            serving = self.server is None or self.server.ready.is_set()
            if not self.ready.is_set() and running and advancing and seq > 0 and serving:
                if self.server is not None:   # a snapshot of the running loop, at once
                    self.server.publish_now()
                self.ready.set()
                self.notifier.ready(f"loop running at {getattr(self.loop, 'fs', 0):g} Hz")
                self.log.info("ready", seq=seq, socket=getattr(self.args, "socket", None))
            now = time.monotonic()
            if wd > 0 and running and advancing and self._cycling() and now - last_wd >= wd:
                self.notifier.watchdog()
                last_wd = now
            self._drain_faults()
            text = self._status_text(seq)
            if text != last_status:
                self.notifier.status(text)
                last_status = text
        self._drain_faults()

    def _cycling(self) -> bool:
        """Is the loop's last cycle younger than its stall bound (the SAFE word; True when
        it is not watched)? WATCHDOG=1 is fed by the loop's progress, not by this thread."""
        from rigd.loop.safeword import W_STALL_BOUND_NS, age_s

        w = getattr(getattr(self.loop, "safe", None), "word", None)
        if w is None:
            return True
        bound, age = int(w[W_STALL_BOUND_NS]), age_s(w)
        return bound <= 0 or age is None or age * 1e9 <= bound

    def _drain_faults(self) -> None:
        q = self._faults
        if q is None:
            return
        while True:
            try:
                ev = q.get_nowait()
            except Exception:  # queue.Empty
                return
            self._fault_text = f"FAULT {ev.get('name')} at cycle {ev.get('seq')}"

    def _status_text(self, seq: int) -> str:
        try:
            st = self.loop.status()
            f = st.get("fault", {})
            fault = f"FAULT {f.get('name')}" if f.get("code") else "ok"
            ctrl = "K∞ on" if st.get("controller", {}).get("enabled") else "K∞ off"
        except Exception:  # noqa: BLE001
            fault, ctrl = "?", "?"
        exp = ""
        if self.experiments is not None:
            es = self.experiments.status()
            if es.get("state") not in (None, "idle"):
                exp = f", experiment {es.get('name')} {es.get('state')}"
        return f"{fault}, {ctrl}{exp}"

