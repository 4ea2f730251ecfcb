"""Files of the runs and config folders as the console offers and serves them.

* Listings never follow a symlink (:func:`walk`): a runs folder with a link to ``/usr`` once
  took 7.3 s and listed 427 outside names; a link is simply not listed (one that stays inside
  can still be opened by its path, :func:`rigd.web.paths.resolve_inside`).
* Uploads are data: kept as ``<runs>/uploads/<time>-<kind>-<name>.yaml`` whatever name they
  came with, served only as plain-text attachments, never offered on the Runs tab; a rejected
  upload is deleted before the answer (:func:`save_upload`, ``app.command``).
* Every other file of the runs folder is served by type (:func:`file_response`): report pages
  as HTML under :data:`REPORT_CSP` (their own inline scripts, nothing fetched, no framing),
  images and text as they are, anything else as an ``application/octet-stream`` attachment.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Iterator
from pathlib import Path

from starlette.responses import FileResponse

from rigd.errors import InputError
from rigd.fileio import atomic_write_text

#: the runs sub-folder of kept uploads
UPLOADS = "uploads"
#: entries a listing looks at, at most (a runs folder of a few hundred runs is ~10 000)
MAX_WALK = 200_000
#: report pages (written by rigd: inline scripts and styles, PNG figures next to them)
REPORT_CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline'; "
              "style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
              "connect-src 'none'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'")
#: uploaded file names: plain words, dots, dashes
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
_TEXT = {".json": "application/json", ".csv": "text/csv; charset=utf-8",
         ".yaml": "text/plain; charset=utf-8", ".yml": "text/plain; charset=utf-8",
         ".txt": "text/plain; charset=utf-8", ".md": "text/plain; charset=utf-8",
         ".log": "text/plain; charset=utf-8"}
_IMAGES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
           ".svg": "image/svg+xml", ".gif": "image/gif", ".webp": "image/webp"}


def walk(root: Path, suffixes: tuple[str, ...], limit: int,
         skip_top: tuple[str, ...] = ()) -> Iterator[Path]:
    """Regular files under ``root`` (not itself a link) whose suffix is in ``suffixes``,
    sorted per folder, at most ``limit``; symlinks and dot-names are neither followed nor
    listed; ``skip_top`` names top-level folders left out; at most :data:`MAX_WALK` entries
    are looked at."""
    if root.is_symlink() or not root.is_dir():
        return
    n, seen = 0, 0
    stack = [root]
    while stack:
        folder = stack.pop()
        try:
            with os.scandir(folder) as it:
                entries = sorted(it, key=lambda e: e.name)
        except OSError:
            continue
        subdirs = []
        for e in entries:
            seen += 1
            if seen > MAX_WALK:
                return
            if e.name.startswith(".") or e.is_symlink():
                continue
            if e.is_dir(follow_symlinks=False):
                if not (folder == root and e.name in skip_top):
                    subdirs.append(Path(e.path))
            elif e.is_file(follow_symlinks=False) and Path(e.name).suffix.lower() in suffixes:
                yield Path(e.path)
                n += 1
                if n >= limit:
                    return
        stack.extend(reversed(subdirs))


def yaml_files(roots: dict[str, Path], limit: int) -> dict[str, list[str]]:
    """YAML files to choose from: every one in the config folder, and those of the runs
    folder with ``controller`` in their path (what ``rigd design`` and kept uploads leave
    there), as ``config/...`` / ``runs/...``."""
    out: dict[str, list[str]] = {}
    for key, root in roots.items():
        out[key] = []
        for p in walk(root, (".yaml",), MAX_WALK):
            rel = p.relative_to(root).as_posix()
            if key == "runs" and "controller" not in rel:
                continue
            out[key].append(f"{key}/{rel}")
            if len(out[key]) >= limit:
                break
    return out


def upload_name(name: object) -> str:
    """The checked base name of an upload (InputError: one line)."""
    base = Path(str(name or "upload.yaml")).name
    if not _NAME.match(base):
        raise InputError(f"upload name {base[:60]!r}: letters, digits, '.', '_', '-' only")
    return base


def save_upload(runs_dir: Path, kind: str, name: str, text: str) -> Path:
    """Keep an upload as ``<runs>/uploads/<UTC time>-<kind>-<stem>.yaml`` (the daemon reads it
    from there; a record of what was run): always a ``.yaml`` name, whatever it came as."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    folder = runs_dir / UPLOADS
    folder.mkdir(parents=True, exist_ok=True)
    stem = Path(name).stem.replace(".", "_") or "upload"
    path = folder / f"{stamp}-{kind}-{stem}.yaml"
    k = 1
    while path.exists():
        k += 1
        path = folder / f"{stamp}-{kind}-{stem}-{k}.yaml"
    atomic_write_text(path, text)
    return path.resolve()


def file_response(runs_dir: Path, path: Path) -> FileResponse:
    """``path`` (inside ``runs_dir``, checked by the caller) served by what it is."""
    rel = path.relative_to(runs_dir)
    suffix = path.suffix.lower()
    if rel.parts[0] == UPLOADS:
        return FileResponse(path, media_type="text/plain; charset=utf-8", filename=path.name,
                            content_disposition_type="attachment")
    if suffix in (".html", ".htm"):
        return FileResponse(path, media_type="text/html; charset=utf-8",
                            headers={"content-security-policy": REPORT_CSP})
    if suffix in _IMAGES or suffix in _TEXT:
        return FileResponse(path, media_type=_IMAGES.get(suffix) or _TEXT[suffix])
    return FileResponse(path, media_type="application/octet-stream", filename=path.name,
                        content_disposition_type="attachment")
