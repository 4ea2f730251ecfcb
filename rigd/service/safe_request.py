"""Request SAFE through the daemon's shared SAFE word (no socket, no client slot, no worker).

Used by ``rigd ctl safe`` and ``rigd web``'s ``POST /api/safe``; layout and rules in
:mod:`rigd.loop.safeword`. The word file sits beside the control socket (``<socket>.safe``)
with the socket's permissions: whoever may use the socket may map it. When it cannot be mapped
(no such file, permission, an old daemon) the caller falls back to the socket's ``safe``
command (:class:`SafeWordUnavailable` says why).
"""

from __future__ import annotations

import asyncio
import mmap
import os
import time
from collections.abc import Iterator
from typing import Any

from rigd.loop import faults as FC
from rigd.loop.safeword import (
    MAGIC,
    N_SLOTS,
    W_ACK_CODE,
    W_ACK_FAULT_SEQ,
    W_ACK_N,
    W_ACK_SEQ,
    W_MAGIC,
    W_PID,
    W_REQ,
    W_SEQ,
    fresh_value,
    word_path,
)


class SafeWordUnavailable(Exception):
    """The SAFE word cannot be used (the message says why); use the socket instead."""


class SafeWordClient:
    """A mapping of the daemon's SAFE word (see module docstring).

    Parameters
    ----------
    socket_path : str
        The daemon's control socket; the word is ``<socket>.safe``.

    Raises
    ------
    SafeWordUnavailable
        No such file, not allowed, or not a rigd SAFE word.
    """

    def __init__(self, socket_path: str) -> None:
        self.path = word_path(socket_path)
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CLOEXEC | os.O_NOFOLLOW)
        except OSError as exc:
            raise SafeWordUnavailable(f"{self.path}: {exc.strerror or exc}") from None
        try:
            st = os.fstat(fd)
            if st.st_size < 8 * N_SLOTS:
                raise SafeWordUnavailable(f"{self.path}: not a rigd SAFE word (too small)")
            self._mm = mmap.mmap(fd, 8 * N_SLOTS, flags=mmap.MAP_SHARED,
                                 prot=mmap.PROT_READ | mmap.PROT_WRITE)
        except OSError as exc:
            raise SafeWordUnavailable(f"{self.path}: {exc.strerror or exc}") from None
        finally:
            os.close(fd)
        self.w = memoryview(self._mm).cast("q")      # aligned 8-byte loads and stores
        if self.w[W_MAGIC] != MAGIC:
            self.close()
            raise SafeWordUnavailable(f"{self.path}: not a rigd SAFE word (bad magic)")

    def close(self) -> None:
        w, self.w = getattr(self, "w", None), None
        if w is not None:
            w.release()
        try:
            self._mm.close()
        except (AttributeError, BufferError):
            pass

    @property
    def seq(self) -> int:
        """The cycle the loop is running now."""
        return int(self.w[W_SEQ])

    def request(self) -> int:
        """Write a request; returns ``c0``, the cycle before it (confirmed by :meth:`ack`)."""
        c0 = int(self.w[W_SEQ])
        self.w[W_REQ] = fresh_value()
        return c0

    def ack(self, c0: int) -> dict[str, Any] | None:
        """The confirmation of a request made at ``c0`` (None while not taken yet)."""
        w = self.w
        if not w[W_ACK_N] or w[W_ACK_SEQ] < c0:
            return None
        code = int(w[W_ACK_CODE])
        return {"safe": True, "via": "safe word", "requested_at": c0,
                "latched_at": int(w[W_ACK_SEQ]), "daemon_pid": int(w[W_PID]),
                "fault": {"code": code, "name": FC.fault_name(code),
                          "text": FC.fault_text(code), "seq": int(w[W_ACK_FAULT_SEQ])}}

    @property
    def daemon_pid(self) -> int:
        """The pid of the daemon that made this word (0: not known)."""
        return int(self.w[W_PID])

    def safe(self, timeout_s: float, alive=None) -> dict[str, Any] | None:
        """Request SAFE and wait up to ``timeout_s`` for the loop's confirmation (None: no
        cycle took it in that time — the loop is not running; the request stays pending).
        Looks at the word with :func:`backoff`'s waits; ``alive()`` (optional) returning
        False ends the wait at once (the daemon is gone: nothing will take it)."""
        c0 = self.request()
        for wait in backoff(timeout_s):
            a = self.ack(c0)
            if a is not None:
                return a
            if alive is not None and not alive():
                break
            time.sleep(wait)
        return self.ack(c0)

    async def safe_async(self, timeout_s: float) -> dict[str, Any] | None:
        """:meth:`safe` for an event loop (waits with ``asyncio.sleep``: holds no thread; a
        word no loop takes costs the event loop a few dozen wake-ups a second at most, not
        one every 0.5 ms)."""
        c0 = self.request()
        for wait in backoff(timeout_s):
            a = self.ack(c0)
            if a is not None:
                return a
            await asyncio.sleep(wait)
        return self.ack(c0)


#: first wait between two looks at the acknowledgement, s: a running loop takes a request in
#: the next cycle (0.2 ms at 5 kHz), so a live daemon is answered after one or two looks
FIRST_WAIT_S = 0.0005
#: longest wait between two looks, s: each wait doubles up to this, so a word that no loop
#: takes (the loop stopped or stuck, a stale file) costs about ``timeout_s / MAX_WAIT_S``
#: looks instead of one every 0.5 ms; a late confirmation is seen at most this late
MAX_WAIT_S = 0.05


def backoff(timeout_s: float) -> Iterator[float]:
    """The waits between looks at a SAFE request's confirmation: :data:`FIRST_WAIT_S`,
    doubling up to :data:`MAX_WAIT_S`, the last one cut at ``timeout_s`` from the first
    (``time.monotonic``); none once that time has passed (the caller then looks once more)."""
    end = time.monotonic() + max(0.0, float(timeout_s))
    wait = FIRST_WAIT_S
    while True:
        left = end - time.monotonic()
        if left <= 0:
            return
        yield min(wait, left)
        wait = min(2 * wait, MAX_WAIT_S)
