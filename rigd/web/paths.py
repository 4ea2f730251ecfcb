"""Every file path that comes from a request is resolved here, inside one of the served roots
(the runs folder, the config folder) or refused.

A request path is relative, ``/``-separated, without ``..``, ``.``-only or empty components,
backslashes or NUL; after resolving symlinks it must still lie inside its root (a symlink
pointing out of the root is refused, one inside is fine).
"""

from __future__ import annotations

import os
from pathlib import Path

#: longest request path, characters
MAX_PATH = 1024


class PathRefused(Exception):
    """A request path that leaves its root or is malformed (-> HTTP 404/400)."""


def resolve_inside(root: str | Path, rel: str) -> Path:
    """The real path of ``rel`` under ``root``; :class:`PathRefused` if it is not inside.

    The file need not exist (the caller checks); its existing ancestors are resolved.
    """
    if not isinstance(rel, str) or not rel or "\x00" in rel or "\\" in rel:
        raise PathRefused("bad path")
    if len(rel) > MAX_PATH:
        raise PathRefused(f"path over {MAX_PATH} characters")
    if rel.startswith("/") or os.path.isabs(rel):
        raise PathRefused("absolute paths are not served")
    parts = rel.split("/")
    if any(p in ("", ".", "..") for p in parts[:-1]) or parts[-1] in (".", ".."):
        raise PathRefused("'..', '.' and empty path components are not allowed")
    if any(len(p.encode("utf-8", "surrogateescape")) > 255 for p in parts):
        raise PathRefused("a path component over 255 bytes")
    try:
        base = Path(root).resolve()
        real = (base / rel.rstrip("/")).resolve()
    except (OSError, RuntimeError) as exc:       # a name too long, a symlink loop
        raise PathRefused(f"bad path: {getattr(exc, 'strerror', None) or exc}") from None
    if real != base and base not in real.parents:
        raise PathRefused("path leaves its folder")
    return real


def split_rooted(value: str, roots: dict[str, Path]) -> Path:
    """Resolve ``"<root>/<rel>"`` (``roots`` maps names like ``config``/``runs`` to folders)."""
    if not isinstance(value, str) or "/" not in value:
        raise PathRefused(f"path must start with one of {', '.join(r + '/' for r in roots)}")
    name, rel = value.split("/", 1)
    if name not in roots:
        raise PathRefused(f"path must start with one of {', '.join(r + '/' for r in roots)}")
    return resolve_inside(roots[name], rel)
