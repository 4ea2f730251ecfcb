"""The console's token and the request guards.

Every state-changing request (any method but GET/HEAD/OPTIONS) must carry
``Authorization: Bearer <token>``; without it (or with a wrong one) the answer is 401 and the
request never reaches a route, so nothing changes. No cookie carries authority, so a page of
another origin cannot make the browser send the token (CSRF-safe: the page keeps the token in
``sessionStorage`` and adds the header itself). Request bodies are limited
(:data:`MAX_BODY`; 413 beyond).
"""

from __future__ import annotations

import hmac
import json
import os
import secrets
import stat
from pathlib import Path

from rigd.errors import InputError

#: largest accepted request body, bytes (an uploaded experiment or controller YAML is a few kB)
MAX_BODY = 1 << 20

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def new_token() -> str:
    """A fresh random token (URL-safe text, 256 bits)."""
    return secrets.token_urlsafe(32)


def load_or_create_token(path: str | Path) -> tuple[str, bool]:
    """Read the token from ``path``, or create the file (mode 0600) with a new token.

    Returns
    -------
    (token, created)

    Raises
    ------
    InputError
        The file is readable or writable by group/others, empty, or unreadable.
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        pass
    except OSError as exc:
        raise InputError(f"cannot create the token file: {exc.strerror or exc}", str(p)) from None
    else:
        token = new_token()
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(token + "\n")
        return token, True
    try:
        st = p.stat()
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the token file: {exc}", str(p)) from None
    if st.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise InputError(f"token file has mode {stat.S_IMODE(st.st_mode):04o}: others could "
                         "read the token (chmod 600 it)", str(p))
    token = text.strip()
    if len(token) < 16 or any(c.isspace() for c in token):
        raise InputError("token file must hold one token of at least 16 characters", str(p))
    return token, False


def token_ok(header: str | None, token: str) -> bool:
    """Whether an ``Authorization`` header value is ``Bearer <token>`` (constant time)."""
    if not header or not header.startswith("Bearer "):
        return False
    given = header[len("Bearer "):].strip().encode("utf-8", "replace")
    return hmac.compare_digest(given, token.encode("utf-8"))


async def _reply(send, status: int, message: str, extra: list | None = None) -> None:
    body = json.dumps({"error": message}).encode()
    headers = [(b"content-type", b"application/json"),
               (b"content-length", str(len(body)).encode())] + (extra or [])
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class Guard:
    """ASGI middleware: the token on state-changing requests, then the body size limit.

    Parameters
    ----------
    app : ASGI app
    token : str
    max_body : int
        Bytes; a longer body (declared or streamed) is refused with 413 before any route runs.
    """

    def __init__(self, app, token: str, max_body: int = MAX_BODY):
        self.app = app
        self.token = token
        self.max_body = max_body

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", [])}
        if scope["method"] not in SAFE_METHODS and not token_ok(headers.get("authorization"),
                                                                self.token):
            return await _reply(send, 401, "missing or wrong token (Authorization: Bearer "
                                "<token>, printed by rigd web at start)",
                                [(b"www-authenticate", b"Bearer")])
        declared = headers.get("content-length")
        if declared is not None:
            try:
                too_big = int(declared) > self.max_body
            except ValueError:
                return await _reply(send, 400, "bad Content-Length")
            if too_big:
                return await _reply(send, 413, f"request body over {self.max_body} bytes")
        if scope["method"] in SAFE_METHODS:
            return await self.app(scope, receive, send)
        # state-changing requests: read the (small) body here, counting, before any route runs
        chunks, seen = [], 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            body = message.get("body", b"")
            seen += len(body)
            if seen > self.max_body:
                return await _reply(send, 413, f"request body over {self.max_body} bytes")
            chunks.append(body)
            if not message.get("more_body", False):
                break
        replay = [{"type": "http.request", "body": b"".join(chunks), "more_body": False}]

        async def replay_receive():
            return replay.pop() if replay else await receive()

        await self.app(scope, replay_receive, send)
