"""The control-socket server: a Unix stream socket speaking JSON lines, in its own thread.

One thread multiplexes every client with :mod:`selectors` (non-blocking sockets), so a slow,
silent or hostile client can never block another one or the loop:

* request lines longer than ``max_line`` bytes are refused with an error reply and the client
  is disconnected (its buffer is bounded);
* a client that does not read its replies is disconnected once ``max_pending`` bytes of
  replies are waiting;
* when ``max_clients`` connections are held and another arrives, the one idle longest (no
  request in flight, no stream, silent for ``evict_idle_s``, default :data:`EVICT_IDLE_S`:
  any) is closed with one error line to make room: idle connections can never lock the
  operator out, whatever their number;
* beyond ``max_clients`` busy connections, :data:`RESERVED` more are accepted for control only
  (:data:`rigd.service.protocol.CONTROL`: ``safe``, reset, the controller, the operating
  point, experiments — a query or a stream there gets one error line saying the daemon is
  full, and is closed): however many clients hold the slots, the operator can still act;
  beyond those, new ones get one error line and are closed;
* a client that completes no request for ``idle_s`` (no request waiting, no push) is closed,
  so idle connections cannot hold the slots for ever: the time counts from its last complete
  (non-empty) request line or the last answer it got, not from its last byte — a client
  trickling a line byte by byte, or sending blank lines, is closed all the same;
* any exception while handling a request becomes an error reply to that client only;
* a request whose answer takes time (a command the socket process forwards to the daemon)
  does not hold the thread: ``handle`` returns a :class:`concurrent.futures.Future` of the
  reply line instead of the line, the server goes on serving every other client, and appends
  the reply when the future is done. That client's later (pipelined) lines wait behind it, so
  its replies stay in request order; while it waits, at most ``max_pending`` bytes of further
  requests are buffered (beyond: dropped);
* a request may start a *push* (``stream.subscribe``): ``handle`` returns ``(reply, pusher)``;
  from then on the thread calls ``pusher.update(now)`` whenever ``pusher.next_due``
  (``time.monotonic``) has passed and appends the line it returns to that client — the same
  ``max_pending`` rule drops a subscriber that stops reading.

The listening socket itself is bound by :func:`rigd.service.listen.listen` (mode ``0660``,
stale files replaced, live daemons refused).
"""

from __future__ import annotations

import errno
import json
import os
import selectors
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path

from rigd.service import protocol
from rigd.service.listen import listen

#: connections accepted beyond ``max_clients``, for control commands only (protocol.CONTROL)
RESERVED = 4
#: a client silent this long may be closed to make room for a new one when every slot is
#: held, s. 0: any idle one, the longest idle first — the newcomer is always the freshest, and
#: a burst of connections is accepted faster than their first requests arrive, so a minimum
#: age would only let a flood of fresh idle connections lock the operator out
EVICT_IDLE_S = 0.0
#: a client that completed no request this long is closed, s (default of
#: ``ControlServer(idle_s=...)``; bytes of an unfinished line do not count)
IDLE_S = 60.0


def _is_control_request(line: bytes) -> bool:
    """Is ``line`` a request for one of the control commands (protocol.CONTROL)?"""
    try:
        req = json.loads(line)
    except (ValueError, RecursionError):
        return False
    return isinstance(req, dict) and req.get("cmd") in protocol.CONTROL


class _Client:
    __slots__ = ("sock", "rbuf", "wbuf", "closing", "closed", "waiting", "push", "reserved",
                 "last")

    def __init__(self, sock: socket.socket, reserved: bool = False):
        self.reserved = reserved
        self.last = time.monotonic()
        self.sock = sock
        self.rbuf = bytearray()
        self.wbuf = bytearray()
        self.closing = False
        self.closed = False
        self.waiting: Future | None = None   # the reply still being worked on
        self.push = None                     # a subscription pushing lines (the live stream)


class ControlServer:
    """Serve ``handle(line) -> reply`` on a Unix socket in a background thread.

    Parameters
    ----------
    path : str or Path
        Socket file.
    handle : callable
        ``bytes -> bytes | Future``: one request line (without ``\\n``) to one reply line, or
        to a future of it (set from any thread; see the module docstring); must not raise
        (see :meth:`rigd.service.protocol.Dispatcher.handle_line`).
    mode : int
        Permissions of the socket file (default 0o660).
    max_line, max_clients, max_pending : int
        Bounds described in the module docstring.
    """

    def __init__(self, path: str | Path, handle: Callable[[bytes], bytes], *, mode: int = 0o660,
                 max_line: int = protocol.MAX_LINE, max_clients: int = 64,
                 max_pending: int = 1 << 20, idle_s: float = IDLE_S,
                 evict_idle_s: float | None = EVICT_IDLE_S):
        self.path = str(path)
        self.handle = handle
        self.mode = mode
        self.max_line = max_line
        self.max_clients = max_clients
        self.max_pending = max_pending
        self.idle_s = idle_s
        #: a client silent this long may be closed for a new one when every slot is held, s
        #: (None: never; the reserved control slots and the refusal at the door remain)
        self.evict_idle_s = evict_idle_s
        self._next_sweep = 0.0
        self._sel = selectors.DefaultSelector()
        self._lsock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop_r, self._stop_w = -1, -1
        self._wake_r, self._wake_w = -1, -1
        self._done: deque[_Client] = deque()   # clients whose future is done (any thread)
        self._clients: dict[int, _Client] = {}
        self._pushing: dict[int, _Client] = {}  # clients with a push subscription
        self._owns_path = False
        self.stats = {"connections": 0, "requests": 0, "dropped_clients": 0,
                      "too_long": 0, "refused_clients": 0, "evicted_clients": 0, "deferred": 0,
                      "pushed": 0,
                      "idle_closed": 0}

    # --- life cycle ---------------------------------------------------------------------
    def start(self, lsock: socket.socket | None = None) -> ControlServer:
        """Bind, set the mode, and start serving. InputError if the path is unusable.

        With ``lsock`` (a listening socket bound by :func:`listen`, e.g. inherited from the
        daemon by the socket process) serve that one; the socket file then belongs to whoever
        bound it and :meth:`stop` leaves it in place.
        """
        if lsock is None:
            lsock = listen(self.path, self.mode)
            self._owns_path = True
        lsock.setblocking(False)
        self._lsock = lsock
        self._stop_r, self._stop_w = os.pipe()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._sel.register(lsock, selectors.EVENT_READ, None)
        self._sel.register(self._stop_r, selectors.EVENT_READ, "stop")
        self._sel.register(self._wake_r, selectors.EVENT_READ, "wake")
        self._thread = threading.Thread(target=self._serve, name="rigd-ctl", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving, close every client and remove the socket file."""
        if self._thread is None:
            return
        try:
            os.write(self._stop_w, b"x")
        except OSError:
            pass
        self._thread.join(5.0)
        self._thread = None
        for c in list(self._clients.values()):
            self._close(c)
        try:
            self._sel.unregister(self._lsock)
        except (KeyError, ValueError):
            pass
        self._lsock.close()
        self._sel.close()
        fds = (self._stop_r, self._stop_w, self._wake_r, self._wake_w)
        self._stop_r = self._stop_w = self._wake_r = self._wake_w = -1  # no late wake-up
        for fd in fds:                                                   # hits a reused fd
            os.close(fd)
        if self._owns_path:
            try:
                os.unlink(self.path)
            except FileNotFoundError:
                pass

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    @property
    def n_clients(self) -> int:
        return len(self._clients)

    # --- the serving thread -------------------------------------------------------------
    def _serve(self) -> None:
        while True:
            for key, events in self._sel.select(self._push_timeout()):
                if key.data == "stop":
                    return
                if key.data == "wake":
                    self._deliver()
                    continue
                if key.data is None:
                    self._accept()
                    continue
                client: _Client = key.data
                try:
                    if events & selectors.EVENT_READ and not client.closing:
                        self._read(client)
                    if events & selectors.EVENT_WRITE:
                        self._flush(client)
                except OSError:
                    self._close(client)
            if self._pushing:
                self._push()
            self._sweep()

    def _sweep(self) -> None:
        """Close the clients silent for ``idle_s`` (about once a second)."""
        now = time.monotonic()
        if now < self._next_sweep:
            return
        self._next_sweep = now + min(1.0, self.idle_s / 2)
        for c in list(self._clients.values()):
            if (c.waiting is None and c.push is None and not c.closed
                    and now - c.last > self.idle_s):
                self.stats["idle_closed"] += 1
                self._close(c)

    def _evict_idlest(self) -> bool:
        """Close the client idle longest (no request in flight, no stream, silent for
        ``evict_idle_s``) with one error line, to make room for a new one. False when
        every held connection is busy or fresh."""
        now = time.monotonic()
        idle = [c for c in self._clients.values()
                if c.waiting is None and c.push is None and not c.closed and not c.wbuf
                and now - c.last >= self.evict_idle_s]
        if not idle:
            return False
        c = min(idle, key=lambda c: c.last)
        self.stats["evicted_clients"] += 1
        try:
            c.sock.send(protocol.error(None, f"closed: every slot (max {self.max_clients}) "
                                             "was held and this connection was idle longest"))
        except OSError:
            pass
        self._close(c)
        return True

    # --- pushed lines (the live stream) ---------------------------------------------------
    def _push_timeout(self) -> float | None:
        sweep = max(0.0, self._next_sweep - time.monotonic()) if self._clients else None
        if not self._pushing:
            return sweep
        due = max(0.0, min(c.push.next_due for c in self._pushing.values()) - time.monotonic())
        return due if sweep is None else min(due, sweep)

    def _push(self) -> None:
        now = time.monotonic()
        for c in list(self._pushing.values()):
            if c.closed or c.push is None:
                continue
            if c.push.next_due > now:
                continue
            try:
                line = c.push.update(now)
            except Exception as exc:  # noqa: BLE001 - a bug ends this push, not the server
                c.push = None
                self._pushing.pop(c.sock.fileno(), None)
                line = protocol.error(None, f"push stopped: internal error: "
                                            f"{type(exc).__name__}: {exc}")
            if not line:
                continue
            self.stats["pushed"] += 1
            c.wbuf += line
            if len(c.wbuf) > self.max_pending:
                self.stats["dropped_clients"] += 1
                self._close(c)
                continue
            try:
                self._flush(c)
            except OSError:
                self._close(c)

    def _accept(self) -> None:
        try:
            sock, _ = self._lsock.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:  # EMFILE etc.: keep serving the others
            if exc.errno in (errno.EMFILE, errno.ENFILE):
                self.stats["refused_clients"] += 1
            return
        self.stats["connections"] += 1
        if len(self._clients) >= self.max_clients and self.evict_idle_s is not None:
            self._evict_idlest()
        reserved = len(self._clients) >= self.max_clients
        if reserved and sum(c.reserved for c in self._clients.values()) >= RESERVED:
            self.stats["refused_clients"] += 1
            try:
                sock.setblocking(False)
                sock.send(protocol.error(None, f"too many clients (max {self.max_clients})"))
            except OSError:
                pass
            sock.close()
            return
        sock.setblocking(False)
        c = _Client(sock, reserved)
        self._clients[sock.fileno()] = c
        self._sel.register(sock, selectors.EVENT_READ, c)

    def _read(self, c: _Client) -> None:
        try:
            data = c.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        if not data:
            c.closing = True
            if not c.wbuf and c.waiting is None:
                self._close(c)
            else:
                self._flush(c)   # the replies still due, then close
            return
        c.rbuf += data
        if c.waiting is not None:
            # its lines wait behind the reply being worked on; bounded like unread replies
            if len(c.rbuf) > self.max_pending:
                self.stats["dropped_clients"] += 1
                self._close(c)
            return
        self._process(c)

    def _process(self, c: _Client) -> None:
        """Answer the complete lines in ``c.rbuf`` until one is deferred, then flush."""
        while c.waiting is None:
            nl = c.rbuf.find(b"\n")
            if nl < 0:
                break
            line = bytes(c.rbuf[:nl]).strip()
            del c.rbuf[:nl + 1]
            if nl > self.max_line:
                self._too_long(c)
                return
            if not line:
                continue
            c.last = time.monotonic()      # the idle time counts from a complete request
            self.stats["requests"] += 1
            if c.reserved and not _is_control_request(line):
                self.stats["refused_clients"] += 1
                c.wbuf += protocol.error(None, f"too many clients (max {self.max_clients}): "
                                               "the daemon is full; only control commands "
                                               "(safe, reset, enable, disable, load, op, "
                                               "start, stop) are taken on this connection")
                c.closing = True
                c.rbuf.clear()
                break
            reply = self.handle(line)
            if isinstance(reply, tuple):          # (reply line, pusher): a subscription
                reply, c.push = reply
                self._pushing[c.sock.fileno()] = c
            if isinstance(reply, Future):
                self.stats["deferred"] += 1
                c.waiting = reply
                reply.add_done_callback(lambda _f, c=c: self._wake(c))
            else:
                c.wbuf += reply
            time.sleep(0)  # hand the GIL to the loop thread if it is waiting
        if c.waiting is None and len(c.rbuf) > self.max_line:
            self._too_long(c)
            return
        if len(c.wbuf) > self.max_pending:
            self.stats["dropped_clients"] += 1
            self._close(c)
            return
        if c.wbuf:
            self._flush(c)
        elif c.closing and c.waiting is None:
            self._close(c)

    def _wake(self, c: _Client) -> None:
        """Future callback (any thread): hand ``c`` to the serving thread."""
        self._done.append(c)
        fd = self._wake_w
        if fd < 0:
            return
        try:
            os.write(fd, b"w")
        except (BlockingIOError, OSError):
            pass  # the pipe is full (a wake-up is already pending) or the server stopped

    def _deliver(self) -> None:
        """In the serving thread: append the replies of finished futures, serve what follows."""
        try:
            while os.read(self._wake_r, 4096):
                pass
        except (BlockingIOError, InterruptedError):
            pass
        while self._done:
            c = self._done.popleft()
            fut = c.waiting
            if c.closed or fut is None or not fut.done():
                continue
            c.waiting = None
            c.last = time.monotonic()          # ... or from its answer
            try:
                c.wbuf += fut.result()
            except Exception as exc:  # noqa: BLE001 - a failed future is an error reply
                c.wbuf += protocol.error(None, f"internal error: {type(exc).__name__}: {exc}")
            try:
                self._process(c)
            except OSError:
                self._close(c)

    def _too_long(self, c: _Client) -> None:
        self.stats["too_long"] += 1
        c.rbuf.clear()
        c.wbuf += protocol.error(None, f"request line longer than {self.max_line} bytes; "
                                       "closing the connection")
        c.closing = True
        self._flush(c)

    def _flush(self, c: _Client) -> None:
        while c.wbuf:
            try:
                n = c.sock.send(c.wbuf)
            except (BlockingIOError, InterruptedError):
                break
            del c.wbuf[:n]
        if c.wbuf:
            self._want_write(c)
        elif c.closing and c.waiting is None:
            self._close(c)
        else:
            # a closing client (EOF read) waiting for its reply: nothing to wait for on it
            # until the reply comes (its end-of-file would make it readable for ever)
            self._events(c, 0 if c.closing else selectors.EVENT_READ)

    def _want_write(self, c: _Client) -> None:
        self._events(c, selectors.EVENT_WRITE if c.closing
                     else selectors.EVENT_READ | selectors.EVENT_WRITE)

    def _events(self, c: _Client, events: int) -> None:
        """Watch ``c`` for ``events`` (0: not at all, for now)."""
        if events == 0:
            try:
                self._sel.unregister(c.sock)
            except (KeyError, ValueError):
                pass
            return
        try:
            self._sel.modify(c.sock, events, c)
        except KeyError:
            self._sel.register(c.sock, events, c)

    def _close(self, c: _Client) -> None:
        c.closed = True
        fd = c.sock.fileno()
        if fd >= 0:
            try:
                self._sel.unregister(c.sock)
            except (KeyError, ValueError):
                pass
            self._clients.pop(fd, None)
            self._pushing.pop(fd, None)
        c.sock.close()

