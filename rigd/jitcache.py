"""Numba's on-disk cache in a folder named by the source it was compiled from.

Numba checks a cached kernel against the time stamp of the kernel's *own* file only. A kernel
that calls a jitted function from another file (the plants' ``plant_step`` calls the film, the
amplifier and the noise of other modules) keeps the machine code it compiled against the old
callee after that file changed: after an upgrade or a checkout the plant returned NaN from
its first cycle until the cache was deleted by hand. :func:`configure` points numba at a
sub-folder of ``NUMBA_CACHE_DIR`` named by a digest of the path, size and modification time of
every ``.py`` file of ``rigd`` and ``rigd_drivers``: any change to any of them starts a fresh
cache (one compilation, ≈ 1 min), and nothing compiled from other source is ever loaded.

``NUMBA_CACHE_DIR`` is the base (``make``, the tests and ``systemd/rigd.service`` set it);
unset — a plain ``rigd`` or ``python -m bench`` from a shell — the base is :func:`default_base`
(the virtual environment's ``numba-cache``, else ``~/.cache/rigd/numba``), never numba's own
default (``__pycache__`` beside each file, where a stale caller survives a changed callee:
``python -m bench reynolds`` ran the plant compiled before 1594f91 that way, 1.74 Newton
iterations per sub-step instead of 1.57). Folders of older source (≈ 11 MB each) are
removed by the first process of a new source tree once unused for :data:`STALE_DAYS` days
(:func:`prune`; that process marks its own folder used), so checkouts and upgrades do not
pile them up; one still in use by an installed copy of other source is at most recompiled.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"
PREFIX = "src-"
#: a ``src-`` folder of other source unused this long is removed (:func:`prune`)
STALE_DAYS = 7.0


def source_roots() -> list[Path]:
    """The folders of ``rigd`` and ``rigd_drivers`` (found without importing the drivers)."""
    roots = [Path(__file__).resolve().parent]
    spec = importlib.util.find_spec("rigd_drivers")
    if spec is not None and spec.submodule_search_locations:
        roots += [Path(p).resolve() for p in spec.submodule_search_locations]
    return roots


def source_digest(roots: list[Path]) -> str:
    """16 hex digits over (relative path, size in bytes, mtime in ns) of every ``.py`` file."""
    h = hashlib.blake2b(digest_size=8)
    for i, root in enumerate(roots):
        for p in sorted(root.rglob("*.py")):
            st = p.stat()
            h.update(f"{i}\0{p.relative_to(root)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def default_base() -> Path:
    """The cache's base when ``NUMBA_CACHE_DIR`` is unset: ``<venv>/numba-cache`` inside a
    virtual environment, else ``$XDG_CACHE_HOME/rigd/numba`` (``~/.cache/rigd/numba``)."""
    if sys.prefix != sys.base_prefix:
        return Path(sys.prefix) / "numba-cache"
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(xdg) / "rigd" / "numba"


def configure(roots: list[Path] | None = None) -> str:
    """Point numba's cache at ``<base>/src-<digest>`` (module docstring); returns that folder.

    Idempotent and inherited: a child process that finds the variable already naming a
    ``src-`` folder takes its parent as the base. Works before and after numba is imported.
    ``roots`` (default :func:`source_roots`): the source folders the digest covers.
    """
    base = os.environ.get(ENV)
    path = Path(base) if base else default_base()
    inherited = path.name.startswith(PREFIX)
    if inherited:
        path = path.parent
    folder = str(path / (PREFIX + source_digest(roots if roots is not None else source_roots())))
    if not inherited:   # once per process tree, not in every child
        prune(path, Path(folder))
    os.environ[ENV] = folder
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.CACHE_DIR = folder
    return folder


def prune(base: Path, current: Path, stale_days: float = STALE_DAYS) -> list[Path]:
    """Mark ``current`` used (its modification time) and remove the other ``src-`` folders
    of ``base`` unused for ``stale_days`` days; returns those removed. Best effort: a base
    that cannot be read or written (a read-only install) is left as it is."""
    import shutil
    import time

    removed = []
    try:
        if current.is_dir():
            os.utime(current)
        limit = time.time() - stale_days * 86400.0
        for p in base.glob(PREFIX + "*"):
            if p != current and p.is_dir() and p.stat().st_mtime < limit:
                shutil.rmtree(p, ignore_errors=True)
                if not p.exists():
                    removed.append(p)
    except OSError:
        pass
    return removed
