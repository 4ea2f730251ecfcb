"""Connections of ``rigd web``: slow clients time out, descriptors cannot run out.

uvicorn's HTTP/1.1 protocol (h11) times out an idle keep-alive connection, but not a client
that sends its request head slowly or never finishes it ("slowloris"): 58 such sockets once
took all 64 descriptors of the process and the console stopped answering. The protocol here
(:func:`guarded_protocol`, given to uvicorn as its ``http`` class) adds two rules:

* **header timeout**: a connection waiting for a request head (new, or idle between
  requests) that has not completed one within ``header_timeout_s`` is closed;
* **connection cap**: at most ``max_connections`` connections at once (sized from the
  descriptor limit at start, :func:`connection_cap`, leaving a reserve for the daemon socket,
  record files and the stream relays); one more closes the oldest connection still waiting
  for a request head, and when every connection is busy with a request the newcomer gets
  ``503`` and is closed.

A request body's own time limit is the guard's (:mod:`rigd.web.guard`, 408).
"""

from __future__ import annotations

import os
import resource

from uvicorn.protocols.http.h11_impl import H11Protocol

from rigd.web.guard import HEADER_TIMEOUT_S

#: descriptors kept free for everything but client connections (daemon socket per request,
#: stream relays, record files, logs)
RESERVE_FDS = 24
#: connections at most whatever the descriptor limit
MAX_CONNECTIONS = 1024

_BUSY_BODY = b'{"error": "too many connections, try again"}'
_BUSY = (b"HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\n"
         b"content-length: %d\r\nconnection: close\r\n\r\n" % len(_BUSY_BODY)) + _BUSY_BODY


def connection_cap(reserve: int = RESERVE_FDS) -> int:
    """Connections the process can hold: the soft descriptor limit minus the descriptors
    open now minus ``reserve`` (at least 4, at most :data:`MAX_CONNECTIONS`)."""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        return MAX_CONNECTIONS
    try:
        used = len(os.listdir("/proc/self/fd"))
    except OSError:
        used = 32
    return int(min(MAX_CONNECTIONS, max(4, soft - used - reserve)))


def guarded_protocol(header_timeout_s: float = HEADER_TIMEOUT_S,
                     max_connections: int | None = None) -> type:
    """An uvicorn h11 protocol class with the header timeout and the connection cap
    (one set of live connections per class: one class per server).

    Parameters
    ----------
    header_timeout_s : float
        Seconds to receive a complete request head (new or idle connection).
    max_connections : int, optional
        Connections at once; default :func:`connection_cap` at the time of the call.
    """
    cap = connection_cap() if max_connections is None else int(max_connections)
    live: dict[GuardedH11Protocol, None] = {}     # insertion order: the oldest first

    class GuardedH11Protocol(H11Protocol):
        header_timeout = header_timeout_s
        max_connections = cap

        def connection_made(self, transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._head_timer = None
            live[self] = None
            self._arm()
            if len(live) > cap:
                victim = next((p for p in live if p is not self and p._waiting()), None)
                if victim is None:
                    transport.write(_BUSY)
                    self._drop()
                else:
                    victim._drop()

        def connection_lost(self, exc) -> None:
            live.pop(self, None)
            self._disarm()
            super().connection_lost(exc)

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if not self._waiting():
                self._disarm()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            if not self.transport.is_closing() and self._waiting():
                self._arm()

        def _waiting(self) -> bool:
            """No request in progress: waiting for (the rest of) a request head."""
            return self.cycle is None or self.cycle.response_complete

        def _arm(self) -> None:
            self._disarm()
            self._head_timer = self.loop.call_later(header_timeout_s, self._expired)

        def _disarm(self) -> None:
            if self._head_timer is not None:
                self._head_timer.cancel()
                self._head_timer = None

        def _expired(self) -> None:
            self._head_timer = None
            if self._waiting():
                self._drop()

        def _drop(self) -> None:
            live.pop(self, None)
            self._disarm()
            if not self.transport.is_closing():
                self.transport.close()

    return GuardedH11Protocol
