"""``GET /api/stream``: the daemon's live stream relayed as Server-Sent Events.

Browsers are *multiplexed* (:class:`StreamHub`): all the browsers that ask for the same
stream settings (rate, points, channels) share ONE control-socket connection, opened with
``stream.subscribe`` (docs/service.md), and at most :data:`MAX_FEEDS` different settings are
served at once — so no number of browsers can take more than a few of the daemon's client
slots. Each browser has a bounded queue of events; one that does not read loses its oldest
events, never holds the others. Each pushed line ``{"stream": {...}}`` becomes one ``data:``
event with the inner object unchanged — its bytes are sliced out of the line, not decoded and
re-encoded (the daemon's socket process already wrote strict JSON; :func:`stream_body`). When
the daemon refuses, stops the push (an error line without request id) or is gone, one
``event: error`` with a one-line ``{"error": ...}`` ends the stream (the page then falls back
to polling ``/api/status``).
"""

from __future__ import annotations

import asyncio
import json
import weakref
from collections.abc import AsyncIterator
from typing import Any

#: bytes of one pushed line at most (a few hundred points x a dozen channels is ~100 kB)
MAX_LINE = 4 << 20
#: a comment line this often keeps proxies and the browser's connection alive, s
KEEPALIVE_S = 15.0


def event(data: Any, name: str | None = None) -> bytes:
    """One SSE event (``event:`` line when named, one ``data:`` line, blank line)."""
    head = f"event: {name}\n" if name else ""
    return (head + "data: " + json.dumps(data, separators=(",", ":")) + "\n\n").encode()


_PREFIX = b'{"stream":'


def stream_body(line: bytes) -> bytes | None:
    """The bytes of the inner object of a pushed line ``{"stream": {...}}``, or None when the
    line is something else (a reply, an error line).

    The socket process writes each push as one JSON object whose only key is ``stream``
    (:meth:`rigd.service.stream.Subscription.update`), so the inner object is the line
    without its prefix and its final ``}``.
    """
    if not line.startswith(_PREFIX):
        return None
    body = line[len(_PREFIX):].strip()
    if not (body.startswith(b"{") and body.endswith(b"}}")):
        return None
    return body[:-1].rstrip()


def data_event(body: bytes) -> bytes:
    """One unnamed SSE event whose ``data:`` line is ``body`` (one line of JSON) as it is."""
    return b"data: " + body + b"\n\n"


async def relay(socket_path: str, subscribe: dict[str, Any],
                timeout: float = 10.0) -> AsyncIterator[bytes]:
    """Subscribe on the daemon socket and yield SSE events until the client goes away
    (the generator is closed; the socket connection is closed with it)."""
    try:
        reader, writer = await asyncio.wait_for(
            asyncio.open_unix_connection(socket_path, limit=MAX_LINE), timeout)
    except (OSError, asyncio.TimeoutError) as exc:
        yield event({"error": f"daemon not reachable: {socket_path}: "
                     f"{getattr(exc, 'strerror', None) or exc or 'timeout'}"}, "error")
        return
    try:
        writer.write((json.dumps({"id": 1, "cmd": "stream.subscribe", **subscribe}) + "\n")
                     .encode())
        await writer.drain()
        try:
            line = await asyncio.wait_for(reader.readline(), timeout)
            reply = json.loads(line) if line else {"ok": False, "error": "daemon closed"}
        except (asyncio.TimeoutError, ValueError) as exc:
            reply = {"ok": False, "error": f"no valid reply to stream.subscribe: {exc!r}"}
        if not reply.get("ok"):
            yield event({"error": "daemon stream unavailable: "
                         + " ".join(str(reply.get("error", "refused")).split())}, "error")
            return
        yield event(reply.get("result") or {}, "subscribed")
        while True:
            try:
                line = await asyncio.wait_for(reader.readline(), KEEPALIVE_S)
            except asyncio.TimeoutError:
                yield b": keepalive\n\n"
                continue
            except (ValueError, asyncio.LimitOverrunError):
                yield event({"error": "stream line too long"}, "error")
                return
            if not line:
                yield event({"error": "daemon closed the stream"}, "error")
                return
            body = stream_body(line)
            if body is not None:
                yield data_event(body)
                continue
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if isinstance(msg, dict) and msg.get("ok") is False and msg.get("id") is None:
                yield event({"error": "daemon stopped the stream: "
                             + " ".join(str(msg.get("error", "")).split())}, "error")
                return
    finally:
        writer.close()
        try:
            await writer.wait_closed()
        except (OSError, ConnectionError):
            pass


#: different stream settings served at once (each one daemon connection)
MAX_FEEDS = 4
#: events waiting for one browser at most; beyond, its oldest are dropped
QUEUE_EVENTS = 32


class StreamFull(Exception):
    """No stream for this browser now (the message says which limit; -> HTTP 503)."""


class _Lease:
    """One browser's place among ``max_streams`` (released once, whatever ends it)."""

    def __init__(self, hub: StreamHub) -> None:
        self._hub: StreamHub | None = hub

    def release(self) -> None:
        hub, self._hub = self._hub, None
        if hub is not None:
            hub.active -= 1


class _Feed:
    """One daemon subscription and the browsers' queues it fans out to.

    :meth:`close` (the last browser left) cancels the task *and* sets :attr:`closed`, which
    the task checks after every event: ``asyncio.wait_for`` before Python 3.12 swallows a
    cancellation that arrives as its awaitable completes (the relay's ``readline`` with a line
    ready: always, on a busy stream), and the subscription then ran on for ever with no
    browser, holding one of the daemon's client slots (seen under ``bench hostile``: one slot
    more after each hostile window)."""

    def __init__(self, hub: StreamHub, key: tuple, subscribe: dict[str, Any]) -> None:
        self.hub, self.key = hub, key
        self.queues: set[asyncio.Queue] = set()
        self.head: bytes | None = None          # the "subscribed" event, for late joiners
        self.closed = False
        self.task = asyncio.get_running_loop().create_task(self._run(subscribe))

    def close(self) -> None:
        """End the subscription (its connection is closed by the task, at once or after the
        event it is waiting for)."""
        self.closed = True
        self.task.cancel()

    async def _run(self, subscribe: dict[str, Any]) -> None:
        events = relay(self.hub.socket_path, subscribe, self.hub.timeout)
        try:
            async for chunk in events:
                if self.closed:
                    break
                if chunk.startswith(b"event: subscribed"):
                    self.head = chunk
                for q in self.queues:
                    _put(q, chunk)
        finally:
            await events.aclose()                   # closes the daemon connection
            if self.hub.feeds.get(self.key) is self:
                del self.hub.feeds[self.key]
            for q in self.queues:
                _put(q, None)                   # the end (after any error event)


def _put(q: asyncio.Queue, item: bytes | None) -> None:
    """Queue ``item`` for one browser; a full queue loses its oldest event (never the end)."""
    while True:
        try:
            q.put_nowait(item)
            return
        except asyncio.QueueFull:
            try:
                q.get_nowait()
            except asyncio.QueueEmpty:
                pass


class StreamHub:
    """The browsers' streams of one ``rigd web`` on at most :data:`MAX_FEEDS` daemon
    connections (see module docstring).

    Parameters
    ----------
    socket_path : str
        The daemon's control socket.
    timeout : float
        Connect / subscribe timeout, s.
    max_streams : int
        Browsers streaming at once.
    """

    def __init__(self, socket_path: str, timeout: float, max_streams: int) -> None:
        self.socket_path, self.timeout, self.max_streams = socket_path, timeout, max_streams
        self.active = 0
        self.feeds: dict[tuple, _Feed] = {}

    def acquire(self, subscribe: dict[str, Any]) -> tuple[_Lease, tuple]:
        """A place for one more browser, taken now (check and count in one step of the event
        loop: no await between, so concurrent requests cannot all pass the check).

        Raises
        ------
        StreamFull
            ``max_streams`` browsers stream already, or ``MAX_FEEDS`` other settings are
            being served.
        """
        key = (subscribe.get("rate_hz"), subscribe.get("points"),
               tuple(subscribe.get("channels") or ()))
        if self.active >= self.max_streams:
            raise StreamFull(f"too many stream clients (at most {self.max_streams})")
        if key not in self.feeds and len(self.feeds) >= MAX_FEEDS:
            raise StreamFull(f"too many different stream settings at once (at most "
                             f"{MAX_FEEDS}; the console's defaults are always served)")
        self.active += 1
        return _Lease(self), key

    def events(self, lease: _Lease, key: tuple, subscribe: dict[str, Any]
               ) -> AsyncIterator[bytes]:
        """This browser's SSE events; the lease is released when the stream ends, however
        (also when the response is dropped before its first event)."""
        gen = self._events(lease, key, subscribe)
        weakref.finalize(gen, lease.release)
        return gen

    async def _events(self, lease: _Lease, key: tuple, subscribe: dict[str, Any]
                      ) -> AsyncIterator[bytes]:
        q: asyncio.Queue = asyncio.Queue(QUEUE_EVENTS)
        feed = None
        try:
            feed = self.feeds.get(key)
            if feed is None:
                feed = self.feeds[key] = _Feed(self, key, subscribe)
            feed.queues.add(q)
            if feed.head is not None:
                yield feed.head
            while True:
                item = await q.get()
                if item is None:
                    return
                yield item
        finally:
            lease.release()
            if feed is not None:
                feed.queues.discard(q)
                if not feed.queues and not feed.task.done():
                    feed.close()            # the last browser left: close the subscription
                    if self.feeds.get(key) is feed:
                        del self.feeds[key]
