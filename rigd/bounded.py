"""Bounded reading of user files: regular files only, size checked before a byte is read.

Every YAML a user names (rig config, controller, experiment, model, weights) is read through
:func:`read_regular`, so no file can make a process read without end or block it:

* the path is ``stat``-ed first: a FIFO, a directory, a device (``/dev/zero``), a socket is
  refused without opening it (opening a FIFO for reading would block until a writer comes);
* it is then opened with ``O_NONBLOCK`` (a FIFO swapped in between the two steps cannot block
  the open) and ``fstat``-ed again: the file read is the file checked;
* its size is compared with the limit before reading, and the read itself stops at
  ``limit + 1`` bytes (a file that grows meanwhile is refused, not read on).

Each refusal is one :class:`~rigd.errors.InputError` naming the file and the problem.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from rigd.errors import InputError

#: largest controller YAML, bytes: an order-64 K∞ with its continuous form, design plant and
#: weights written at full precision is about 0.8 MB
MAX_CONTROLLER_BYTES = 4 << 20
#: largest experiment YAML, bytes (the shipped ones are below 2 kB)
MAX_EXPERIMENT_BYTES = 256 << 10
#: largest rig configuration YAML, bytes
MAX_CONFIG_BYTES = 1 << 20
#: largest other YAML a user names (model files, design weights, operating-range tables)
MAX_YAML_BYTES = 16 << 20

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def _kind(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.3g} MiB" if n >= 1 << 20 else f"{n / 1024:.3g} kiB"


def check_regular(st: os.stat_result, path: str, limit: int, what: str) -> None:
    """Raise :class:`InputError` unless ``st`` is a regular file of at most ``limit`` bytes."""
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{what} must be a regular file, this is {_kind(st.st_mode)}", path)
    if st.st_size > limit:
        raise InputError(f"{what} is {_mib(st.st_size)}, larger than the limit of "
                         f"{_mib(limit)}; not read", path)


def read_regular(path: str | Path, limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file ``path`` (at most ``limit`` bytes; see module docstring).

    Parameters
    ----------
    path : str or Path
    limit : int
        Largest accepted size, bytes.
    what : str
        What the file is, for the message ("controller file", ...).

    Raises
    ------
    InputError
        Missing, unreadable, not a regular file, or larger than ``limit``.
    """
    p = str(path)
    try:
        check_regular(os.stat(p), p, limit, what)
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
                     | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise InputError("no such file", p) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", p) from None
    try:
        check_regular(os.fstat(fd), p, limit, what)   # the file opened is the file checked
        chunks, n = [], 0
        while n <= limit:
            b = os.read(fd, min(1 << 20, limit + 1 - n))
            if not b:
                break
            chunks.append(b)
            n += len(b)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", p) from None
    finally:
        os.close(fd)
    if n > limit:
        raise InputError(f"{what} grew beyond the limit of {_mib(limit)} while read; not used",
                         p)
    return b"".join(chunks)


def read_text(path: str | Path, limit: int = MAX_YAML_BYTES, what: str = "file") -> str:
    """:func:`read_regular` decoded as UTF-8 (:class:`InputError` if it is not)."""
    data = read_regular(path, limit, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what} is not UTF-8 text (byte {exc.start})", str(path)) from None


def confined(path: str | Path, root: str | Path, what: str) -> Path:
    """``path`` resolved (symlinks followed, ``..`` folded), if it lies strictly inside
    ``root`` (resolved too); :class:`InputError` naming ``what`` otherwise.

    A symlink inside ``root`` that points out of it is refused like the outside path itself.
    """
    real = Path(os.path.realpath(path))
    base = Path(os.path.realpath(root))
    if real == base or base not in real.parents:
        raise InputError(f"must be inside the runs folder {base} (resolves to {real})", what)
    return real
