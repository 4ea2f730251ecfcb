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
iterations per sub-step instead of 1.57). Folders of older source stay until removed
(≈ 11 MB each).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"
PREFIX = "src-"


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
    if path.name.startswith(PREFIX):
        path = path.parent
    folder = str(path / (PREFIX + source_digest(roots if roots is not None else source_roots())))
    os.environ[ENV] = folder
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.CACHE_DIR = folder
    return folder
