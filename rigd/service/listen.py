"""Bind the control socket's listening Unix socket: mode, stale files, live daemons.

The socket file is created with mode ``0660`` (owner and group only; see docs/service.md for
the ``rigd`` group) and never exists with wider permissions. A stale socket file left by a
crashed daemon is replaced; a live one (another daemon answering) is refused.
"""

from __future__ import annotations

import os
import socket
import stat
from pathlib import Path

from rigd.errors import InputError


def listen(path: str | Path, mode: int = 0o660, backlog: int = 64) -> socket.socket:
    """Bind a listening Unix stream socket at ``path`` with permissions ``mode``.

    The file never exists with wider permissions (umask set around ``bind``). A stale socket
    file (nobody answering) is replaced; a live one, or a path that is not a socket, is refused
    with :class:`~rigd.errors.InputError`.
    """
    path = str(path)
    _prepare_path(path)
    ls = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_CLOEXEC)
    old = os.umask(0o777 & ~mode)  # never world-accessible, not even for an instant
    try:
        ls.bind(path)
    except OSError as exc:
        ls.close()
        raise InputError(f"cannot bind control socket: {exc.strerror}", path) from None
    finally:
        os.umask(old)
    os.chmod(path, mode)
    ls.listen(backlog)
    return ls


def _prepare_path(path: str) -> None:
    p = Path(path)
    if len(os.fsencode(path)) > 107:
        raise InputError("socket path too long (Unix sockets allow 107 bytes)", path)
    if not p.parent.is_dir():
        raise InputError("socket directory does not exist", str(p.parent))
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if not stat.S_ISSOCK(st.st_mode):
        raise InputError("exists and is not a socket; refusing to replace it", path)
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.settimeout(0.5)
        probe.connect(path)
    except OSError:
        os.unlink(path)  # stale socket of a dead daemon
        return
    finally:
        probe.close()
    raise InputError("another daemon is listening on this socket", path)
