"""``GET /api/stream``: the daemon's live stream relayed as Server-Sent Events.

One control-socket connection per SSE client, opened with ``stream.subscribe``
(docs/service.md): each pushed line ``{"stream": {...}}`` becomes one ``data:`` event with the
inner object unchanged. When the daemon refuses or is gone, one ``event: error`` with a one-line
``{"error": ...}`` ends the stream (the page then falls back to polling ``/api/status``).
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
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if isinstance(msg, dict) and "stream" in msg:
                yield event(msg["stream"])
    finally:
        writer.close()
        try:
            await writer.wait_closed()
        except (OSError, ConnectionError):
            pass
