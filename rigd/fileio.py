"""Atomic file writing: a file appears whole or not at all, with the caller's umask.

The temporary file is created beside the target with ``os.open(..., O_CREAT | O_EXCL, 0o666)``
so the kernel applies the process umask exactly as for a plain ``open(path, "w")`` (0644
under umask 022, 0640 under 027). ``tempfile.mkstemp`` is not used: it creates 0600 and the
renamed file would keep it — a controller designed by an engineer unreadable by the ``rigd``
service user, a report that cannot be served. (Reading the umask with ``os.umask`` would
briefly change it for every thread of the process, so it is never touched here.)
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

#: permission bits asked of the kernel for a new file, before the umask (as ``open()`` does)
NEW_FILE_MODE = 0o666
_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)


def _temp_name(path: Path) -> Path:
    """A hidden, unique-enough temporary name beside ``path`` (48 random bits)."""
    return path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp"


def create_temp_beside(path: str | Path) -> tuple[int, Path]:
    """Create a new, empty, uniquely named hidden file beside ``path``.

    Returns
    -------
    (fd, tmp)
        An open write-only descriptor and the temporary file's path. Its permissions are
        ``0o666 & ~umask``.
    """
    path = Path(path)
    for _ in range(100):
        tmp = _temp_name(path)
        try:
            return os.open(tmp, _FLAGS, NEW_FILE_MODE), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name beside {path}")  # pragma: no cover


@contextmanager
def atomic_open(path: str | Path, mode: str = "w", *, replace: bool = True,
                **kwargs) -> Iterator[IO]:
    """Open a temporary file beside ``path``; rename it onto ``path`` only on success.

    On any exception the temporary file is removed and ``path`` is left untouched. The file
    gets the caller's umask (see the module docstring); ``mode`` is a write mode of
    :func:`open` (``"w"``, ``"wb"``). ``replace=False``: FileExistsError (and ``path``
    untouched) if ``path`` exists by then — for records, which are never replaced.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp: Path | None = None
    try:
        # the temporary name is known before the file exists: a KeyboardInterrupt (SIGINT
        # during a manifest write) that lands between os.open and the assignment still finds
        # it and removes it — no stray '.name.XXXX.tmp' beside a run's records
        for _ in range(100):
            tmp = _temp_name(path)
            try:
                fd = os.open(tmp, _FLAGS, NEW_FILE_MODE)
                break
            except FileExistsError:
                tmp = None
                continue
        else:  # pragma: no cover
            raise FileExistsError(f"no free temporary name beside {path}")
        try:
            fh = open(fd, mode, **kwargs)  # noqa: SIM115 - the `with fh:` below closes it
        except BaseException:
            os.close(fd)
            raise
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        if replace:
            os.replace(tmp, path)
        else:
            rename_new(tmp, path)
    except BaseException:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


def rename_new(src: str | Path, dst: str | Path) -> None:
    """Rename ``src`` to ``dst`` only if ``dst`` does not exist (FileExistsError otherwise):
    never replaces a file. A hard link then the unlink of ``src`` (atomic refusal); where the
    filesystem has no hard links, a checked ``os.rename``."""
    try:
        os.link(src, dst)
    except FileExistsError:
        raise
    except OSError:
        if os.path.lexists(dst):
            raise FileExistsError(f"{dst} exists") from None
        os.rename(src, dst)
        return
    os.unlink(src)
