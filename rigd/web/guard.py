"""The request guard of ``rigd web``: an ASGI middleware that runs before any route.

In order: the ``Host`` header against the accepted names (400: DNS rebinding), the head's
size (431), the request target's length (414) and its names' (404), the token or session
(401; 403 for a command with the read-only token; ``POST /api/login`` and ``/api/logout``
are answered here), then the body: its size (413, declared or counted as it streams) and
the time it may take to arrive (408). Only the console page and its static files (``/``,
``/static/...``) are served without a token: they hold no rig data.
"""

from __future__ import annotations

import asyncio
import json

from rigd.web.auth import Access, Tokens

#: largest accepted request body, bytes (an uploaded experiment or controller YAML is a few kB)
MAX_BODY = 1 << 20
#: longest request target (path and query), bytes
MAX_TARGET = 2048
#: largest request head, bytes: what arrives in pieces is cut at this size by h11
#: (``rigd web``), what arrives whole is refused here (431)
MAX_HEAD = 16 * 1024
#: longest file name in a request path, bytes (the file system's limit)
MAX_NAME = 255
#: seconds a connection may wait for a complete request head (rigd.web.conn), and a request
#: body may take to arrive, whole (both: ``rigd web --header-timeout``)
HEADER_TIMEOUT_S = BODY_TIMEOUT_S = 10.0
#: methods that change nothing
READ_METHODS = frozenset({"GET", "HEAD"})
LOGIN, LOGOUT = "/api/login", "/api/logout"


def public(method: str, path: str) -> bool:
    """Served without a token: the console page and its static files (no rig data)."""
    return method in READ_METHODS and (path in ("/", "/favicon.ico")
                                       or path.startswith("/static/"))


def host_name(header: str | None) -> str | None:
    """The name of a ``Host`` header without port, lower case (``[::1]:80`` -> ``::1``)."""
    if not header:
        return None
    h = header.strip().lower()
    if h.startswith("["):
        end = h.find("]")
        return h[1:end] if end > 0 else None
    return h.rsplit(":", 1)[0] if h.count(":") == 1 else h


async def reply(send, status: int, payload: dict, extra: list | None = None) -> None:
    """A JSON response sent straight from the guard (``{"error": ...}`` or a result)."""
    body = json.dumps(payload).encode()
    headers = [(b"content-type", b"application/json"), (b"cache-control", b"no-store"),
               (b"content-length", str(len(body)).encode())] + (extra or [])
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


def _error(send, status: int, message: str, extra: list | None = None):
    return reply(send, status, {"error": message}, extra)


class Guard:
    """ASGI middleware: host, target length, token/session, body size and time.

    Parameters
    ----------
    app : ASGI app
    tokens : Tokens
    max_body : int
        Bytes; a longer body (declared or streamed) is refused with 413 before any route runs.
    allowed_hosts : tuple of str, optional
        Accepted ``Host`` names (lower case, without port); None accepts any.
    body_timeout_s : float
        Seconds a request body may take to arrive (408 beyond).
    """

    def __init__(self, app, tokens: Tokens, max_body: int = MAX_BODY,
                 allowed_hosts: tuple[str, ...] | None = None,
                 body_timeout_s: float = BODY_TIMEOUT_S):
        self.app = app
        self.tokens = tokens
        self.max_body = max_body
        self.allowed = None if allowed_hosts is None else {h.lower() for h in allowed_hosts}
        self.body_timeout_s = body_timeout_s

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", [])}
        if self.allowed is not None and host_name(headers.get("host")) not in self.allowed:
            return await _error(send, 400, "Host header not accepted by this server (add the "
                                "name with rigd web --allow-host)")
        method, path = scope["method"], scope["path"]
        if sum(len(k) + len(v) + 4 for k, v in scope.get("headers", [])) > MAX_HEAD:
            return await _error(send, 431, f"request headers over {MAX_HEAD} bytes")
        if len(scope.get("raw_path") or b"") + len(scope.get("query_string") or b"") > MAX_TARGET:
            return await _error(send, 414, f"request target over {MAX_TARGET} bytes")
        if any(len(part.encode("utf-8", "replace")) > MAX_NAME for part in path.split("/")):
            return await _error(send, 404, f"no such file (a name over {MAX_NAME} bytes)")
        if not public(method, path):
            refused = await self._check_access(scope, headers, send)
            if refused:
                return
        declared = headers.get("content-length")
        if declared is not None:
            try:
                too_big = int(declared) > self.max_body
            except ValueError:
                return await _error(send, 400, "bad Content-Length")
            if too_big:
                return await _error(send, 413, f"request body over {self.max_body} bytes")
        if method in READ_METHODS:
            return await self.app(scope, receive, send)
        body = await self._read_body(receive, send)
        if body is None:
            return
        replay = [{"type": "http.request", "body": body, "more_body": False}]

        async def replay_receive():
            return replay.pop() if replay else await receive()

        await self.app(scope, replay_receive, send)

    async def _check_access(self, scope, headers, send) -> bool:
        """Answer the request here when it is refused or is a login/logout; True if answered."""
        method, path = scope["method"], scope["path"]
        access = self.tokens.of_header(headers.get("authorization"))
        if method == "POST" and path == LOGIN:
            if access is Access.NONE:
                await self._unauthorized(send)
            else:
                await reply(send, 200, {"access": access.name.lower()},
                            [(b"set-cookie", self.tokens.new_session().encode())])
            return True
        if method == "POST" and path == LOGOUT:
            await reply(send, 200, {"access": "none"}, [(b"set-cookie", self.tokens.drop_session(
                headers.get("cookie")).encode())])
            return True
        if method in READ_METHODS:
            if access is Access.NONE and not self.tokens.session_ok(headers.get("cookie")):
                await self._unauthorized(send)
                return True
            return False
        if access is Access.CONTROL:
            return False
        if access is Access.READ:
            await _error(send, 403, "read-only token: commands need the control token "
                         "(--token-file)")
        else:
            await self._unauthorized(send)
        return True

    @staticmethod
    def _unauthorized(send):
        return _error(send, 401, "missing or wrong token (Authorization: Bearer <token>, "
                      "printed by rigd web at start)", [(b"www-authenticate", b"Bearer")])

    async def _read_body(self, receive, send) -> bytes | None:
        """The whole (small) body, counted as it arrives; None when answered (413, 408) or
        the client went away."""
        chunks, seen = [], 0
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.body_timeout_s
        while True:
            try:
                message = await asyncio.wait_for(receive(), max(0.0, deadline - loop.time()))
            except asyncio.TimeoutError:
                await _error(send, 408, f"request body not received within "
                             f"{self.body_timeout_s:g} s")
                return None
            if message["type"] == "http.disconnect":
                return None
            body = message.get("body", b"")
            seen += len(body)
            if seen > self.max_body:
                await _error(send, 413, f"request body over {self.max_body} bytes")
                return None
            chunks.append(body)
            if not message.get("more_body", False):
                return b"".join(chunks)
