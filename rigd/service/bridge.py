"""The daemon's side of the socket process (:mod:`rigd.service.frontend`).

The control socket is served by a separate, *spawned* process so that nothing a client does —
a flood of queries, malformed lines, huge requests — competes with the real-time loop thread
for this process's interpreter lock. This module, in the daemon (the loop's process):

* binds the socket (:func:`rigd.service.server.listen`: mode 0660, stale file replaced, live
  one refused) and keeps the listening socket open, so the socket file stays valid while the
  socket process starts or restarts (connections wait in the listen backlog);
* spawns the socket process with the listening socket and two connections;
* a **publisher** thread sends a *snapshot* (status, timing, faults, experiment state, ping
  info; pickled through a pipe) ``rate_hz`` times a second and at once after each command —
  the only per-second cost a client can cause in this process is fixed by ``rate_hz``;
* a **command** thread receives the requests the socket process has already validated and
  hands them to a **worker** thread, which runs them one after the other through
  :class:`~rigd.service.protocol.Dispatcher` (which validates again) and replies with the
  reply line and a fresh snapshot; ``safe`` is run at once by the command thread itself, so
  the safe state never waits behind a slow command (a large ``controller.load``);
* if the socket process dies it is logged and spawned again (the loop never notices).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

from rigd.service import spawned
from rigd.service.listen import listen

#: snapshot publication rate, Hz (queries are at most this stale)
SNAPSHOT_HZ = 25.0


class SocketFrontend:
    """Run the control socket in a spawned process (see module docstring).

    Parameters
    ----------
    path : str
        Socket file.
    mode : int
        Its permissions (0o660).
    handle_command : callable
        ``(bytes[, payload]) -> bytes``: one validated command line (and what the socket
        process read for it: a packed controller, a validated experiment) to its reply line
        (the daemon's :meth:`Dispatcher.handle_line`); must not raise.
    snapshot : callable
        ``() -> dict`` with ``status``, ``timing``, ``faults``, ``experiment`` (None when
        experiments are unavailable) and ``info`` (ping fields).
    rate_hz : float
        Snapshot rate.
    log : structlog logger, optional
    nice : int
        Niceness of the socket process, at least (it is not time-critical; the loop is);
        absolute, not added to the daemon's.
    helper_priority : int, optional
        SCHED_FIFO priority of the publisher and command threads (best effort): just below
        the loop thread's, like the loop's other helper threads. They share the interpreter
        lock with the loop thread; preempted by ordinary processes while holding it, they
        would stall the loop (priority inversion).
    ring : rigd.loop.shared_ring.RingHandle, optional
        The recorder's ring in shared memory; the socket process maps it read-only and serves
        ``stream.subscribe`` from it (without it the stream is refused).
    fs_hz : float, optional
        The loop's rate (the socket process refuses controllers for another one).
    runs_root : str, optional
        The daemon's runs folder (the socket process refuses a ``run_dir`` outside it).
    idle_s : float, optional
        A client that completed no request this long is closed, s (default
        :data:`rigd.service.server.IDLE_S`).
    evict_s : float or "never", optional
        When every slot is held, the client idle longest (at least this long, s) is closed to
        make room for a new one (default :data:`rigd.service.server.EVICT_IDLE_S`; "never").
    word : callable, optional
        Called once the socket is bound (the SAFE word file goes beside it): returns the
        loop's SAFE word handle (:class:`rigd.loop.safeword.WordHandle`) or None.
    gates : dict, optional
        The config's ``controller_gates`` as plain values, for the socket process's checks.
    """

    def __init__(self, path: str, mode: int, handle_command: Callable[[bytes], bytes],
                 snapshot: Callable[[], dict[str, Any]], *, rate_hz: float = SNAPSHOT_HZ,
                 log=None, nice: int = 10, max_clients: int = 64,
                 helper_priority: int | None = None, ring=None,
                 safe_generation: Callable[[], int] | None = None,
                 fs_hz: float | None = None, runs_root: str | None = None,
                 idle_s: float | None = None, evict_s: float | str | None = None,
                 gates: dict[str, Any] | None = None,
                 word: Callable[[], Any] | None = None):
        self.path = str(path)
        self.mode = mode
        self.handle_command = handle_command
        self._generation = safe_generation
        self._snapshot_fn = snapshot
        self.period = 1.0 / rate_hz
        self.log = log
        self.helper_priority = helper_priority
        self.opts = {"path": self.path, "nice": nice, "max_clients": max_clients,
                     "ring": ring, "fs_hz": fs_hz, "runs_root": runs_root, "idle_s": idle_s,
                     "evict_s": evict_s, "gates": gates}
        #: called once the socket is bound: the loop's SAFE word handle for the socket
        #: process (status and ping read the loop's liveness from it), or None
        self._word_fn = word
        self.ready = threading.Event()
        self.restarts = 0
        self.pid: int | None = None
        self._lsock = None
        self._proc = None
        self._snap_w = None
        self._cmd = None
        self._version = 0
        self._vlock = threading.Lock()
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._threads: list[threading.Thread] = []
        self._work: queue.SimpleQueue = queue.SimpleQueue()   # commands for the worker
        self._send_lock = threading.Lock()      # replies come from two threads

    # --- life cycle ---------------------------------------------------------------------
    def start(self) -> SocketFrontend:
        """Bind the socket (InputError if unusable), spawn the socket process, start threads."""
        self._lsock = listen(self.path, self.mode)
        if self._word_fn is not None:
            self.opts["word"] = self._word_fn()
        self._spawn()
        for target, name in ((self._publish_run, "rigd-snapshot"),
                             (self._command_run, "rigd-commands"),
                             (self._work_run, "rigd-command-worker")):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)
        return self

    def stop(self) -> None:
        """Stop the socket process, close the socket and remove its file."""
        self._stop.set()
        self._wake.set()
        self._work.put(None)
        for t in self._threads:
            t.join(5.0)
        self._threads.clear()
        self._end_process()
        if self._lsock is not None:
            self._lsock.close()
            self._lsock = None
            try:
                os.unlink(self.path)
            except FileNotFoundError:
                pass

    def _spawn(self) -> None:
        ctx = multiprocessing.get_context("spawn")
        snap_r, snap_w = ctx.Pipe(duplex=False)
        cmd_here, cmd_there = ctx.Pipe(duplex=True)
        # named by module: this (the loop's) process never imports the socket process's
        # request handling nor its file readers (import contract, pyproject.toml)
        proc = ctx.Process(target=spawned.call, name="rigd-socket", daemon=True,
                           args=("rigd.service.frontend", "main", self._lsock, snap_r,
                                 cmd_there, self.opts))
        proc.start()
        snap_r.close()
        cmd_there.close()
        self._proc, self._snap_w, self._cmd = proc, snap_w, cmd_here
        self.ready.clear()
        self._wake.set()   # the first snapshot at once: the process waits for it to serve

    def _end_process(self) -> None:
        proc, self._proc = self._proc, None
        for c in (self._snap_w, self._cmd):
            if c is not None:
                c.close()          # EOF: the socket process stops serving and exits
        self._snap_w = self._cmd = None
        if proc is None:
            return
        proc.join(5.0)
        if proc.is_alive():
            proc.terminate()
            proc.join(2.0)
        if proc.is_alive():
            proc.kill()
            proc.join(2.0)

    def _restart(self, why: str) -> None:
        code = self._proc.exitcode if self._proc is not None else None
        self._end_process()
        if self._stop.is_set():
            return
        self.restarts += 1
        if self.log is not None:
            self.log.error("socket process died, starting it again", reason=why,
                           exitcode=code, restarts=self.restarts)
        time.sleep(min(0.5 * self.restarts, 5.0))  # no spawn storm if it keeps dying
        if not self._stop.is_set():
            self._spawn()

    # --- snapshot ------------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        with self._vlock:          # numbered when started: a later start always wins
            self._version += 1
            v = self._version
        snap = self._snapshot_fn()
        snap["v"] = v
        return snap

    def publish_now(self) -> None:
        """Publish a snapshot at once (after a state change outside the socket's commands)."""
        self._wake.set()

    def _publish_run(self) -> None:
        as_helper(self.helper_priority)
        while not self._stop.is_set():
            self._wake.wait(self.period)
            self._wake.clear()
            conn = self._snap_w
            if conn is None or self._stop.is_set():
                continue
            try:
                conn.send(self.snapshot())
            except (OSError, ValueError, EOFError):
                time.sleep(self.period)  # the process is gone; the command thread restarts it
            except Exception as exc:  # noqa: BLE001 - a broken snapshot must not end publishing
                if self.log is not None:
                    self.log.error("snapshot failed", error=repr(exc))
                time.sleep(1.0)

    # --- commands --------------------------------------------------------------------------
    def _command_run(self) -> None:
        as_helper(self.helper_priority)
        while not self._stop.is_set():
            conn, proc = self._cmd, self._proc
            if conn is None or proc is None:
                time.sleep(0.05)
                continue
            try:
                if not conn.poll(0.25):
                    if not proc.is_alive():
                        self._restart("exited")
                    continue
                kind, tag, line, meta = conn.recv()
            except (OSError, EOFError, ValueError):
                if not self._stop.is_set():
                    proc.join(1.0)
                    self._restart("connection closed")
                continue
            if kind == "ready":
                self.pid = tag
                self.ready.set()
                continue
            if _is_safe(line):    # the safety button never waits behind a slow command
                self._reply(conn, tag, self.handle_command(line))
                continue
            gen = self._generation() if self._generation is not None else None
            deadline = meta.get("deadline") if isinstance(meta, dict) else None
            payload = meta.get("payload") if isinstance(meta, dict) else None
            self._work.put((conn, tag, line, gen, deadline, payload))

    def _work_run(self) -> None:
        """Worker thread: runs the forwarded commands one after the other (but ``safe``).

        A command that waited here past its deadline, or that a SAFE overtook while it waited,
        is answered "dropped" and not run (applied when answered, or never)."""
        as_helper(self.helper_priority)
        while True:
            item = self._work.get()
            if item is None:
                return
            conn, tag, line, gen, deadline, payload = item
            why = ""
            if deadline is not None and time.monotonic() > deadline:
                why = "it waited behind other commands past its deadline"
            elif gen is not None and self._generation() != gen:
                why = "overtaken by SAFE (sent before the safe state was requested)"
            if why:
                self._reply(conn, tag, _dropped(line, why))
                continue
            self._reply(conn, tag, self.handle_command(line, gen, deadline) if payload is None
                        else self.handle_command(line, gen, deadline, payload))

    def _reply(self, conn, tag: int, reply: bytes) -> None:
        snap = self.snapshot()
        with self._send_lock:
            try:
                conn.send(("reply", tag, reply, snap))
            except (OSError, ValueError, EOFError):
                pass   # the socket process is gone (its successor does not wait for this)

    @property
    def n_clients(self) -> int:
        return 0  # counted by the socket process (``ping`` -> clients)


def _dropped(line: bytes, why: str) -> bytes:
    """The reply to a command dropped before it ran."""
    from rigd.service import protocol

    try:
        req = json.loads(line)
        req_id, cmd = req.get("id"), req.get("cmd")
    except (ValueError, AttributeError):
        req_id, cmd = None, "command"
    if isinstance(req_id, (dict, list)):
        req_id = None
    return protocol.error(req_id, f"{cmd}: not run, dropped: {why}; it will never be applied")


def _is_safe(line: bytes) -> bool:
    """Is this (already validated) command line the ``safe`` command?"""
    try:
        return json.loads(line).get("cmd") == "safe"
    except (ValueError, AttributeError):
        return False


def as_helper(priority: int | None) -> None:
    """Give the calling thread SCHED_FIFO ``priority`` (best effort, silent; None: leave it)."""
    if priority is None:
        return
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(max(1, int(priority))))
    except (OSError, AttributeError, ValueError):
        pass
