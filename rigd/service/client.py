"""A small blocking client for the control socket (used by ``rigd ctl``, ``rigd web``, the
benches and the tests)."""

from __future__ import annotations

import itertools
import json
import socket
import time
from collections.abc import Iterator
from typing import Any

from rigd.errors import DaemonGone, InputError

DEFAULT_SOCKET = "/run/rigd/rigd.sock"
#: longest request line the daemon takes, bytes (rigd.service.protocol.MAX_LINE)
MAX_REQUEST = 64 * 1024


def command_timeout(wait_s: float) -> float:
    """The ``timeout_s`` a client waiting ``wait_s`` for its reply sends: early enough that
    the daemon's "dropped" answer (its deadline plus the socket process's grace) arrives
    before the client gives up."""
    wait_s = float(wait_s)
    return round(0.6 * wait_s if wait_s < 5.0 else wait_s - 2.0, 3)


def controller_args(path: str) -> dict[str, Any]:
    """``controller.load``'s arguments for the controller file ``path``, read here with the
    caller's own rights (:mod:`rigd.bounded`: a regular file within the size limit), parsed
    and checked as the loader does, and sent as its content (:func:`rigd.controller.to_wire`):
    the daemon opens no file a client names.

    Raises
    ------
    InputError
        The file cannot be read by this user, or is not a valid controller (one line).
    """
    import os

    from rigd.controller import load_controller, to_wire

    p = os.path.abspath(path)
    return {"path": p, "controller": to_wire(load_controller(p))}


def experiment_args(path: str) -> dict[str, Any]:
    """``experiment.start``'s arguments for the experiment file ``path``: its text, read here
    with the caller's own rights (size-limited; the socket process validates it), and its
    name (the daemon opens no file a client names)."""
    import os

    from rigd.bounded import MAX_EXPERIMENT_BYTES
    from rigd.configio import read_text

    p = os.path.abspath(path)
    text = read_text(p, MAX_EXPERIMENT_BYTES, "experiment file")
    return {"path": p, "text": text}


class ControlError(Exception):
    """The daemon replied ``ok: false``; the message is the daemon's one line."""


class ControlClient:
    """Connect to the daemon's socket and send requests.

    Parameters
    ----------
    path : str
        Socket file (default :data:`DEFAULT_SOCKET`).
    timeout : float
        Seconds to wait for a reply (the daemon answers in milliseconds).
    """

    def __init__(self, path: str = DEFAULT_SOCKET, timeout: float = 10.0):
        self.path = path
        self.timeout = timeout
        self._sock: socket.socket | None = None
        self._buf = b""
        self._ids = itertools.count(1)
        self.subscribed: dict[str, Any] | None = None

    def connect(self) -> ControlClient:
        end = time.monotonic() + (self.timeout or 10.0)
        while True:
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.settimeout(self.timeout)
            try:
                s.connect(self.path)
                break
            except BlockingIOError:
                # the listen backlog is full (a flood of connections being accepted and
                # refused): try again until the timeout, then say so
                s.close()
                if time.monotonic() > end:
                    raise InputError("cannot connect: the daemon's connection backlog stays "
                                     "full (too many clients connecting)", self.path) from None
                time.sleep(0.01)
                continue
            except FileNotFoundError:
                s.close()
                raise InputError("no daemon socket here (is rigd running? see --socket)",
                                 self.path) from None
            except PermissionError:
                s.close()
                raise InputError("permission denied (are you in the rigd group?)",
                                 self.path) from None
            except ConnectionRefusedError:
                s.close()
                raise DaemonGone("the daemon is not running: its socket is left, but nothing "
                                 "listens on it (it ended)", self.path) from None
            except OSError as exc:
                s.close()
                raise InputError(f"cannot connect: {exc.strerror or exc}", self.path) from None
        self._sock = s
        return self

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self):
        return self.connect() if self._sock is None else self

    def __exit__(self, *exc):
        self.close()

    def send_raw(self, data: bytes) -> None:
        """Send raw bytes (for tests of malformed requests)."""
        self._sock.sendall(data)

    def _send(self, data: bytes) -> None:
        """Send a request; a connection the daemon already closed (it refused this client at
        the door: one error line, then close) is an :class:`InputError` carrying that line,
        never a bare ``BrokenPipeError`` (which ``rigd``'s main takes for a closed stdout)."""
        try:
            self._sock.sendall(data)
        except (BrokenPipeError, ConnectionResetError):
            said = self._pending_error()
            if said:          # refused at the door (full): the daemon is there and said why
                raise InputError(f"the daemon closed the connection before the request: "
                                 f"{said}", self.path) from None
            raise self._gone_or("the daemon closed the connection before the request "
                                "was sent") from None

    def _pending_error(self) -> str:
        """The error line the daemon wrote before closing, if it is waiting here ("")."""
        try:
            self._sock.setblocking(False)
            while b"\n" not in self._buf:
                chunk = self._sock.recv(65536)
                if not chunk:
                    break
                self._buf += chunk
        except OSError:
            pass
        line = self._buf.split(b"\n", 1)[0]
        try:
            return str(json.loads(line).get("error") or "")
        except (ValueError, AttributeError):
            return ""

    def _gone_or(self, what: str) -> InputError:
        """The error for a connection the daemon's side closed: :class:`DaemonGone` when no
        daemon listens on the socket any more (it ended), else an :class:`InputError`
        saying ``what``."""
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        probe.settimeout(1.0)
        try:
            probe.connect(self.path)
        except (ConnectionRefusedError, FileNotFoundError):
            return DaemonGone(f"the daemon ended: {what}, and nothing listens on the socket "
                              f"any more (a request in flight may or may not have been "
                              f"applied)", self.path)
        except OSError:
            pass
        finally:
            probe.close()
        return InputError(what, self.path)

    def read_reply(self) -> dict[str, Any]:
        """Read one reply line."""
        while b"\n" not in self._buf:
            try:
                chunk = self._sock.recv(65536)
            except TimeoutError:
                raise InputError(f"no reply within {self.timeout:g} s", self.path) from None
            except ConnectionResetError:
                chunk = b""
            if not chunk:
                raise self._gone_or("daemon closed the connection"
                                    + (" in the middle of a reply" if self._buf else
                                       " without a reply"))
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        try:
            return json.loads(line)
        except ValueError:
            raise InputError(f"the daemon's reply is not JSON: {bytes(line[:80])!r}",
                             self.path) from None

    def request(self, cmd: str, **args: Any) -> dict[str, Any]:
        """Send one request; return the whole reply object (``ok`` true or false).

        The request carries ``timeout_s`` (:func:`command_timeout`): a command the daemon has
        not applied by then is dropped, never applied later, and the reply says so before
        this client stops waiting.
        """
        if self._sock is None:
            self.connect()
        rid = next(self._ids)
        req = {"id": rid, "cmd": cmd, **args}
        if self.timeout:
            req["timeout_s"] = command_timeout(self.timeout)
        data = (json.dumps(req) + "\n").encode()
        if len(data) > MAX_REQUEST:
            raise InputError(f"{cmd}: the request is {len(data)} bytes, more than the "
                             f"{MAX_REQUEST} a request line may have (is the file that "
                             f"large?)", self.path)
        self._send(data)
        reply = self.read_reply()
        if reply.get("id") != rid:
            if reply.get("id") is None and reply.get("ok") is False:
                raise InputError(f"the daemon refused the connection: {reply.get('error')}",
                                 self.path)
            raise InputError(f"reply id {reply.get('id')!r} does not match request {rid}",
                             self.path)
        return reply

    def call(self, cmd: str, **args: Any) -> Any:
        """Send one request; return its ``result`` or raise :class:`ControlError`."""
        reply = self.request(cmd, **args)
        if not reply.get("ok"):
            raise ControlError(reply.get("error", "error"))
        return reply.get("result")

    def stream(self, rate_hz: float = 50.0, points: int = 200,
               channels: list[str] | None = None) -> Iterator[dict[str, Any]]:
        """Subscribe to the live stream and yield its updates (docs/service.md "Live stream").

        Parameters
        ----------
        rate_hz : float
            Updates per second (10–100).
        points : int
            Most min/max points per channel per update.
        channels : list of str, optional
            Record channels (default: all).

        Yields
        ------
        dict
            The ``stream`` object of each update (``seq``, ``t_s``, ``wall_ns``, ``n``,
            ``dropped``, ``t``, ``min``, ``max``, ``status``). The subscription's ``result``
            (``fs_hz``, ``channels``...) is in :attr:`subscribed` (the subscription is sent
            when this method is called, not at the first update).

        Raises
        ------
        ControlError
            The daemon refused the subscription (its one line).
        ControlError
            The daemon stopped the push (an error line with no request id, e.g. ``push
            stopped: ...``): raised at once with that line, never left to a time-out.
        rigd.errors.InputError
            The connection closed or no update came within ``timeout``. Use the client on a
            connection of its own (replies to other requests on it are skipped).
        """
        self.subscribed = self.call("stream.subscribe", rate_hz=rate_hz, points=points,
                                    channels=channels)
        return self._updates()

    def _updates(self) -> Iterator[dict[str, Any]]:
        while True:
            msg = self.read_reply()
            if "stream" in msg:
                yield msg["stream"]
            elif msg.get("ok") is False and msg.get("id") is None:
                raise ControlError(msg.get("error", "the daemon stopped the stream"))
