"""The socket process: the control socket served outside the loop's process.

The daemon (:mod:`rigd.service.bridge`) binds the socket and *spawns* this process (a fresh
interpreter, not a fork), handing it the listening socket and two multiprocessing
connections. Here, in a process of its own — its own interpreter lock, a lower CPU priority
(``nice`` +10) — :class:`~rigd.service.server.ControlServer` talks to every client:

* every request line is parsed and validated here (:func:`rigd.service.protocol.parse_request`);
  malformed, unknown or invalid requests are answered here and **never reach the loop's
  process**;
* ``status``, ``timing``, ``faults``, ``experiment.status`` and ``ping`` are answered from the
  latest *snapshot* the daemon publishes (``snapshot_hz``, default 25 Hz, and after every
  command) — a flood of queries costs the loop's process nothing;
* ``stream.subscribe`` is served here too, from the recorder's ring buffer in shared memory
  (mapped read-only) and the snapshot: :mod:`rigd.service.stream` — the live stream costs the
  loop's process nothing;
* valid commands (``fault.reset``, ``safe``, ``controller.*``, ``operating_point.set``,
  ``experiment.start``/``stop``), at most :data:`MAX_COMMANDS_PER_S` per second and
  :data:`MAX_IN_FLIGHT` at once, are forwarded to the daemon's command thread, which runs
  them in order through :class:`~rigd.service.protocol.Dispatcher` and replies with the
  result and a fresh snapshot. Forwarding never holds the server's thread: the handler
  returns a future of the reply (the server serves every other client meanwhile, queries
  included), a sender thread writes to the daemon and a receiver thread completes the futures
  as the replies come back (or with an error after :data:`COMMAND_TIMEOUT_S`). ``safe`` is
  never refused by the rate limit (the safety button must always get through).
* the files named by ``controller.load`` and ``experiment.start`` are read here, by a reader
  thread (:mod:`rigd.service.reader`: regular files only, size limits checked before
  reading, parsed and validated — at most :data:`MAX_READS` waiting); only the result, packed
  (a controller as its matrices, an experiment as its validated spec), is forwarded with the
  command: the loop's process never reads, parses nor validates a file a client names. A
  ``run_dir`` outside the daemon's runs folder (symlinks resolved) is refused here too.

The process ignores SIGINT, SIGTERM and SIGHUP (the daemon handles them and stops this process
itself) and exits when its connection to the daemon closes (the daemon died or stopped).
"""

from __future__ import annotations

import json
import os
import queue
import signal
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from rigd.errors import InputError
from rigd.loop.shared_ring import RingReader
from rigd.plain import plain
from rigd.service import liveview, protocol, reader
from rigd.service.protocol import (
    RequestError,
    check_content,
    check_paths,
    error,
    parse_envelope,
)
from rigd.service.server import ControlServer
from rigd.service.stream import StreamHub

#: requests answered from the snapshot (no round trip to the loop's process)
QUERIES = ("status", "timing", "faults", "experiment.status", "ping")

#: longest wait for the daemon to run a forwarded command, s
COMMAND_TIMEOUT_S = 60.0

#: after a command's deadline the daemon's "dropped" reply is waited for this long before this
#: process answers so itself, s
REPLY_GRACE_S = 0.5

#: commands forwarded to the loop's process per second, all clients together (token bucket
#: with this burst too): bounds what even a flood of *valid* commands can cost the loop's
#: process; an operator or the experiment runner sends a few per second
MAX_COMMANDS_PER_S = 50.0

#: forwarded commands waiting for the daemon at once, all clients together; beyond it a
#: command is refused at once (the daemon runs them one after the other)
MAX_IN_FLIGHT = 32

#: commands whose file is read and validated here before they are forwarded
READ_FIRST = ("controller.load", "experiment.start")

#: files being read (or waiting to be) at once, all clients together; beyond, refused at once
MAX_READS = 4


class SnapshotHandler:
    """``handle_line`` of the socket process: answer queries from the snapshot, forward commands.

    Parameters
    ----------
    cmd_conn : multiprocessing.connection.Connection
        Duplex connection to the daemon's command thread.
    clients : callable
        Number of connected clients (for ``ping``).
    max_commands_per_s : float
        Commands beyond this rate (burst as large) are refused with an error reply.
    max_in_flight : int
        Commands forwarded and not yet answered, at most; beyond, refused with an error reply.
    timeout_s : float
        A forwarded command not answered by the daemon within this time gets an error reply.
    ring : rigd.loop.shared_ring.RingHandle, optional
        The recorder's ring (``stream.subscribe``); None: the stream is refused.
    fs_hz : float, optional
        The loop's rate: a controller for another rate is refused here.
    runs_root : str, optional
        The daemon's runs folder: an ``experiment.start`` ``run_dir`` outside it is refused
        here (None: left to the daemon).
    gates : dict, optional
        The rig config's ``controller_gates`` (:meth:`rigd.rigconfig.LoadedConfig.
        gate_options`): a controller above the gain bound, or unstable on the nominal plant
        when it has no design plant, is refused here.
    """

    def __init__(self, cmd_conn, clients=lambda: 0,
                 max_commands_per_s: float = MAX_COMMANDS_PER_S,
                 max_in_flight: int = MAX_IN_FLIGHT, timeout_s: float = COMMAND_TIMEOUT_S,
                 ring=None, fs_hz: float | None = None, runs_root: str | None = None,
                 gates: dict | None = None, word=None):
        self.cmd_conn = cmd_conn
        #: the loop's SAFE word, read-only (rigd.service.liveview: status and ping as the
        #: loop is now); None: answered from the snapshot alone
        self._word = word.map() if word is not None else None
        self.fs_hz = fs_hz
        self.runs_root = runs_root
        self.gates = gates
        self._reader = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rigd-reader")
        self._reading = 0
        self.streams = StreamHub(RingReader(ring) if ring is not None else None,
                                 lambda: self._snap)
        self.clients = clients
        self.rate = float(max_commands_per_s)
        self.max_in_flight = int(max_in_flight)
        self.timeout_s = float(timeout_s)
        self._tokens = self.rate
        self._t_tokens = time.monotonic()
        self.forwarded = 0
        self.throttled = 0
        self._lock = threading.Lock()          # snapshot
        self._have = threading.Event()
        self._snap: dict[str, Any] = {"v": -1}
        self._encoded: dict[str, bytes] = {}   # query -> JSON of its result, for this version
        self._tag = 0
        # forwarded commands: tag -> (future of the reply line, request id, deadline)
        self._pending: dict[int, tuple[Future, Any, float]] = {}
        self._plock = threading.Lock()
        self._channel_closed = False
        self._outq: queue.SimpleQueue = queue.SimpleQueue()
        self._threads = [threading.Thread(target=self._send_run, name="rigd-cmd-send",
                                          daemon=True),
                         threading.Thread(target=self._receive_run, name="rigd-cmd-recv",
                                          daemon=True)]
        for t in self._threads:
            t.start()

    def close(self, timeout: float = 5.0) -> None:
        """Stop the sender; commands still waiting get an error reply."""
        self._outq.put(None)
        self._reader.shutdown(wait=False, cancel_futures=True)
        self._fail_all("the socket process is stopping")
        self._threads[0].join(timeout)

    @property
    def in_flight(self) -> int:
        """Commands forwarded and not yet answered."""
        return len(self._pending)

    # --- snapshot ------------------------------------------------------------------------
    def install(self, snap: dict[str, Any]) -> None:
        """Take ``snap`` if it is newer than the one held (snapshots carry a version)."""
        with self._lock:
            if snap.get("v", -1) <= self._snap.get("v", -1):
                return
            self._snap = snap
            self._encoded = {}
        self._have.set()

    def _result_json(self, cmd: str) -> bytes:
        with self._lock:
            hit = self._encoded.get(cmd)
            if hit is not None:
                return hit
            snap = self._snap
        if cmd == "experiment.status" and snap.get("experiment") is None:
            raise RequestError(f"{cmd}: experiments are not available in this daemon")
        value = {"faults": snap.get("faults", [])} if cmd == "faults" else snap.get(
            "experiment" if cmd == "experiment.status" else cmd, {})
        enc = json.dumps(plain(value), separators=(",", ":"),
                         allow_nan=False).encode()
        with self._lock:
            if self._snap is snap:
                self._encoded[cmd] = enc
        return enc

    def _status_json(self) -> bytes:
        """``status`` overlaid with the SAFE word: reads its own writes, shows a stall."""
        with self._lock:
            st = self._snap.get("status") or {}
        return json.dumps(plain(liveview.status(st, self._word)), separators=(",", ":"),
                          allow_nan=False).encode()

    # --- requests ----------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes | Future | tuple:
        """One request line to one reply line, to a future of it for a forwarded command, or
        to ``(reply line, subscription)`` for ``stream.subscribe``; never raises (the
        ``ControlServer`` contract)."""
        req_id = None
        try:
            req_id, cmd, args, timeout_s = parse_envelope(line)
            if cmd == "stream.subscribe":
                try:
                    result, sub = self.streams.subscribe(args.rate_hz, args.points,
                                                         args.channels)
                except LookupError as exc:
                    raise RequestError(str(exc), req_id) from None
                return protocol.ok(req_id, result), sub
            if cmd not in QUERIES:
                check_paths(cmd, args, self.runs_root)  # refusals that need no loop state
                check_content(cmd, args)
                if cmd != "safe" and not self._take_token():
                    self.throttled += 1
                    raise RequestError(f"{cmd}: too many commands (more than {self.rate:g} "
                                       f"per second from all clients); not run, try again",
                                       req_id)
                if cmd in READ_FIRST:
                    return self._read_then_forward(line, req_id, cmd, args, timeout_s)
                return self._forward(line, req_id, cmd, timeout_s)
            if not self._have.wait(10.0):
                raise RequestError("the daemon has not published its state yet")
            if cmd == "ping":
                with self._lock:
                    info = dict(self._snap.get("info", {}))
                    st = self._snap.get("status") or {}
                why = liveview.not_cycling(st, self._word)
                if why is not None:      # alive only while the loop cycles
                    raise RequestError(f"ping: {why}", req_id)
                return protocol.ok(req_id, {"pong": True, **info, "clients": self.clients(),
                                            "socket_pid": os.getpid(),
                                            "commands_waiting": self.in_flight})
            body = (self._status_json() if cmd == "status" and self._word is not None
                    else self._result_json(cmd))
            head = json.dumps({"id": plain(req_id)}, separators=(",", ":"))[:-1]
            return head.encode() + b',"ok":true,"result":' + body + b"}\n"
        except RequestError as exc:
            return error(exc.req_id if exc.req_id is not None else req_id, str(exc))
        except Exception as exc:  # noqa: BLE001 - a bug is reported to its client only
            return error(req_id, f"internal error: {type(exc).__name__}: {exc}")

    def _take_token(self) -> bool:
        now = time.monotonic()
        self._tokens = min(self.rate, self._tokens + (now - self._t_tokens) * self.rate)
        self._t_tokens = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

    def _read_then_forward(self, line: bytes, req_id: Any, cmd: str, args,
                           timeout_s: float | None = None) -> Future | bytes:
        """Read and validate the command's file (or inline spec) in the reader thread, then
        forward the command with the packed result; a future of the reply line (an error
        line at once if :data:`MAX_READS` reads are already waiting)."""
        with self._plock:
            if self._reading >= MAX_READS:
                return error(req_id, f"{cmd}: {self._reading} files are already being read; "
                                     f"not run, try again")
            self._reading += 1
        out: Future = Future()
        t0 = time.monotonic()

        def work() -> None:
            try:
                if cmd == "controller.load":
                    payload = reader.read_controller(args.controller.model_dump(), args.path,
                                                     self.fs_hz, self.gates)
                else:
                    payload = reader.read_experiment(args.path, args.spec, args.text)
            except InputError as exc:
                out.set_result(error(req_id, str(exc)))
                return
            except Exception as exc:  # noqa: BLE001 - a bug is reported to its client only
                out.set_result(error(req_id, f"{cmd}: internal error: "
                                             f"{type(exc).__name__}: {exc}"))
                return
            finally:
                with self._plock:
                    self._reading -= 1
            # the client's wait started when it asked: the reading counts against it
            left = (self.timeout_s if timeout_s is None else timeout_s) - (time.monotonic() - t0)
            if left <= 0:
                out.set_result(error(req_id, f"{cmd}: dropped, not run: reading the file took "
                                             f"longer than the client waits"))
                return
            fwd = self._forward(line, req_id, cmd, left, payload)
            if isinstance(fwd, bytes):
                out.set_result(fwd)
            else:
                fwd.add_done_callback(lambda f: out.set_result(f.result()))

        try:
            self._reader.submit(work)
        except RuntimeError:      # shut down: the process is stopping
            with self._plock:
                self._reading -= 1
            return error(req_id, "the socket process is stopping")
        return out

    def _forward(self, line: bytes, req_id: Any, cmd: str,
                 timeout_s: float | None = None, payload: Any = None) -> Future | bytes:
        """Queue ``line`` (with the ``payload`` read for it: a packed controller, a validated
        experiment) for the daemon; a future of its reply line (an error line at once if
        the channel is closed or too many commands are waiting).

        The command's *deadline* (``time.monotonic()``, the same clock in every process) is
        its client's ``timeout_s`` from now, at most :attr:`timeout_s`; it travels with the
        command: the daemon drops it rather than apply it after that (docs/service.md "Applied
        when answered, or never"), and answers so; this process answers so itself a little
        after the deadline if the daemon did not.
        """
        fut: Future = Future()
        wait = self.timeout_s if timeout_s is None else min(timeout_s, self.timeout_s)
        deadline = time.monotonic() + wait
        with self._plock:
            if self._channel_closed:
                return error(req_id, "the daemon's command channel is closed (stopping?)")
            if len(self._pending) >= self.max_in_flight and cmd != "safe":
                return error(req_id, f"{cmd}: {len(self._pending)} commands are already "
                                     f"waiting for the daemon; not run, try again")
            self._tag += 1
            tag = self._tag
            self._pending[tag] = (fut, req_id, deadline + REPLY_GRACE_S)
        self.forwarded += 1
        meta = {"deadline": deadline, "timeout_s": wait}
        if payload is not None:
            meta["payload"] = payload
        self._outq.put(("cmd", tag, line, meta))
        return fut

    def _finish(self, tag: int, reply: bytes) -> None:
        with self._plock:
            entry = self._pending.pop(tag, None)
        if entry is not None:          # None: the late answer to a command that timed out
            entry[0].set_result(reply)

    def _fail_all(self, why: str) -> None:
        with self._plock:
            self._channel_closed = True
            entries, self._pending = list(self._pending.values()), {}
        for fut, req_id, _ in entries:
            fut.set_result(error(req_id, why))

    def _send_run(self) -> None:
        """Sender thread: the only writer of commands to the daemon (never the server's)."""
        while True:
            item = self._outq.get()
            if item is None:
                return
            try:
                self.cmd_conn.send(item)
            except (OSError, EOFError, ValueError, TypeError):
                self._fail_all("the daemon's command channel is closed (stopping?)")
                return

    def _receive_run(self) -> None:
        """Receiver thread: replies to their futures; commands past their deadline to an error."""
        while True:
            try:
                if self.cmd_conn.poll(0.25):
                    kind, tag, reply, snap = self.cmd_conn.recv()
                    if snap is not None:
                        self.install(snap)
                    if kind == "reply":
                        self._finish(tag, reply)
            except (OSError, EOFError, ValueError, TypeError):
                self._fail_all("the daemon's command channel is closed (stopping?)")
                return
            now = time.monotonic()
            with self._plock:
                late = [t for t, (_, _, end) in self._pending.items() if end < now]
                entries = [(t, self._pending.pop(t)) for t in late]
            for _, (fut, req_id, _) in entries:
                fut.set_result(error(req_id, "the daemon did not answer the command by its "
                                             "deadline; it was dropped and will never be "
                                             "applied (`status` shows the state)"))


def main(lsock, snap_conn, cmd_conn, opts: dict[str, Any]) -> None:
    """Entry point of the spawned socket process (see module docstring)."""
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_IGN)
    try:  # never real-time (a respawn from a SCHED_FIFO helper thread would inherit it)
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError):
        pass
    try:  # niceness 10, not 10 *more* than the daemon's: a daemon started niced (a test run,
        # `nice rigd run`) would put this process at 19 and starve it on a busy machine
        # (measured under load: no stream update nor ping reply for 30 s)
        cur = os.getpriority(os.PRIO_PROCESS, 0)
        os.setpriority(os.PRIO_PROCESS, 0, max(cur, int(opts.get("nice", 10))))
    except OSError:
        pass
    idle, evict = opts.get("idle_s"), opts.get("evict_s")
    server = ControlServer(opts["path"], lambda line: b"",
                           max_clients=opts.get("max_clients", 64),
                           **({} if idle is None else {"idle_s": float(idle)}),
                           **({} if evict is None else
                              {"evict_idle_s": None if evict == "never" else float(evict)}))
    handler = SnapshotHandler(cmd_conn, clients=lambda: server.n_clients,
                              ring=opts.get("ring"), fs_hz=opts.get("fs_hz"),
                              runs_root=opts.get("runs_root"), gates=opts.get("gates"),
                              word=opts.get("word"))
    server.handle = handler.handle_line
    # the first snapshot before serving, then tell the daemon we are up
    try:
        if snap_conn.poll(30.0):
            handler.install(snap_conn.recv())
    except (OSError, EOFError):
        return
    reader.warm_up()   # the readers' imports before serving, not at the first request
    try:               # the nominal plant read once, before serving (the config's file)
        reader.gates_for(opts.get("gates"))
    except InputError:
        pass           # refused with its reason at each controller.load
    try:
        cmd_conn.send(("ready", os.getpid(), None, None))  # before serving: one sender at a time
    except (OSError, EOFError):
        return
    server.start(lsock)
    try:
        while True:
            handler.install(snap_conn.recv())
    except (OSError, EOFError):
        pass  # the daemon closed the connection: stop serving
    finally:
        server.stop()
        handler.close()
