"""``GET /api/stream``: the daemon's live stream relayed as Server-Sent Events.

One control-socket connection per SSE client, opened with ``stream.subscribe``
(docs/service.md): each pushed line ``{"stream": {...}}`` becomes one ``data:`` event with the
inner object unchanged — its bytes are sliced out of the line, not decoded and re-encoded (the
daemon's socket process already wrote strict JSON; :func:`stream_body`). When the daemon
refuses, stops the push (an error line without request id) or is gone, one ``event: error``
with a one-line ``{"error": ...}`` ends the stream (the page then falls back to polling
``/api/status``).
"""

from __future__ import annotations

import asyncio
import json
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
