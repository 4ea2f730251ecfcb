"""The console's tokens and sessions.

Two tokens (docs/web.md, "Security"): the **control** token (``--token-file``) allows every
request; the optional **read** token (``--read-token-file``) allows reads only (GET/HEAD)
and is answered 403 on a command. Either is sent as ``Authorization: Bearer <token>``.

A browser's ``EventSource`` and a report page opened from a link cannot send that header, so
``POST /api/login`` with either token in the header answers a **session cookie**
(``rigd_session``: random, ``HttpOnly``, ``SameSite=Strict``, ``Secure`` under TLS, 12 h)
that carries *read* access only: a command always needs the control token in the header, so a
page of another origin that makes the browser send the cookie changes nothing (no CSRF), and
no token is ever sent in a URL (URLs end up in logs and browser history): the login URL that
``rigd web`` prints carries the control token in its fragment, which the browser keeps to
itself, and the page takes it out of the address bar (``rigd.cli.web.login_url``).
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import os
import secrets
import stat
import time
from pathlib import Path

from rigd.errors import InputError

#: name of the session cookie
COOKIE = "rigd_session"
#: life of a session, s
SESSION_S = 12 * 3600
#: sessions kept at once (the oldest is dropped beyond)
MAX_SESSIONS = 256


class Access(enum.IntEnum):
    """What a request may do."""

    NONE = 0
    READ = 1          # GET/HEAD of everything behind the token
    CONTROL = 2       # and the commands


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
        if not stat.S_ISREG(st.st_mode) or st.st_size > 4096:
            raise InputError("token file must be a regular file of one line", str(p))
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


def _digest(text: str) -> bytes:
    return hashlib.sha256(text.encode("utf-8", "replace")).digest()


class Tokens:
    """The tokens of one ``rigd web`` and its read sessions (in memory: a restart ends them).

    Parameters
    ----------
    control : str
        Token of every request.
    read : str, optional
        Token of reads only (GET/HEAD); None: no read-only token.
    secure : bool
        Serving over TLS: the session cookie gets ``Secure``.
    """

    def __init__(self, control: str, read: str | None = None, secure: bool = False):
        if read is not None and hmac.compare_digest(read.encode(), control.encode()):
            raise InputError("the read-only token must differ from the control token")
        self.control, self.read, self.secure = control, read, secure
        self._sessions: dict[bytes, float] = {}     # sha256(session id) -> expiry (monotonic)

    def of_header(self, header: str | None) -> Access:
        """The access an ``Authorization`` header gives."""
        if token_ok(header, self.control):
            return Access.CONTROL
        if self.read is not None and token_ok(header, self.read):
            return Access.READ
        return Access.NONE

    def new_session(self) -> str:
        """A new read session; returns its ``Set-Cookie`` header value."""
        now = time.monotonic()
        self._sessions = {k: t for k, t in self._sessions.items() if t > now}
        while len(self._sessions) >= MAX_SESSIONS:
            self._sessions.pop(min(self._sessions, key=self._sessions.__getitem__))
        sid = secrets.token_urlsafe(32)
        self._sessions[_digest(sid)] = now + SESSION_S
        return (f"{COOKIE}={sid}; Path=/; HttpOnly; SameSite=Strict; Max-Age={SESSION_S}"
                + ("; Secure" if self.secure else ""))

    def drop_session(self, cookie_header: str | None) -> str:
        """End the session named in a ``Cookie`` header; returns a ``Set-Cookie`` value that
        clears the cookie."""
        sid = session_id(cookie_header)
        if sid is not None:
            self._sessions.pop(_digest(sid), None)
        return f"{COOKIE}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0"

    def session_ok(self, cookie_header: str | None) -> bool:
        """Whether a ``Cookie`` header carries a live session."""
        sid = session_id(cookie_header)
        if sid is None:
            return False
        expiry = self._sessions.get(_digest(sid))
        return expiry is not None and expiry > time.monotonic()


def session_id(cookie_header: str | None) -> str | None:
    """The ``rigd_session`` value of a ``Cookie`` header (None when absent)."""
    for part in (cookie_header or "").split(";"):
        name, sep, value = part.strip().partition("=")
        if sep and name == COOKIE and value:
            return value
    return None
