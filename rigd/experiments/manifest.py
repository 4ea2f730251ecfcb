"""Run directories and their ``manifest.json``.

Every experiment run writes into a NEW directory (never reused, nothing overwritten)::

    RUN_DIR/
      manifest.json                     # rewritten atomically after every point
      p000_w0_p4_prbs.h5                # one or more records per operating point
      p001_w3000_p4_impact_k0_r0.h5 ...

``manifest.json`` (format ``rigd_manifest: 1``)::

    {"rigd_manifest": 1, "experiment": {"name", "kind", "source", "spec", "spec_sha256"},
     "status": "running" | "complete" | "interrupted" | "failed"
               | "interrupted (process ended)",
     "owner": {"host", "pid", "start_ticks"},   # the process writing it (rigd.owner)
     "started": ISO, "finished": ISO | null, "host": str, "mode": "lockstep" | "realtime",
     "source": "simulated" | "rig", "drivers": {"fast": name, "slow": [names]},
     "software": {"rigd_version", "python", "numpy", "h5py"},
     "config": {"path": str | null, "sha256": str | null}, "fs_hz": float,
     "points": [{"index", "omega_rpm", "p_inj_bar", "status": "done" | "missing" | "failed"
                 | "not_settled" | "running", "files": [names], "error": str | null,
                 "started", "finished", "recording": "NAME.h5.part" | null}],
     "files": [{"path", "point", "kind", "omega_rpm", "p_inj_bar", "n_frames",
                "controller_on", "repeat", ..., "complete": false, "incomplete_reason"}],
                # complete/incomplete_reason only on a record cut short
     "missing": [point indices not completed], "message": str,
     "fault": {"seq", "code", "name", "text"} | null}   # the latched fault that ended the run
"""

from __future__ import annotations

import datetime as _dt
import errno
import hashlib
import json
import os
import platform
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rigd import __version__
from rigd.data.manifest import MANIFEST
from rigd.errors import InputError
from rigd.fileio import atomic_write_text
from rigd.owner import this_process

#: a run folder's reserve (dot-name: not listed), given back when the disk fills or the run
#: ends, and its size, bytes
RESERVE = ".rigd-reserve"
RESERVE_BYTES = 1 << 20


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def sha256_text(text: str | bytes | None) -> str | None:
    if text is None:
        return None
    if isinstance(text, str):
        text = text.encode("utf-8")
    return "sha256:" + hashlib.sha256(text).hexdigest()


def software() -> dict[str, str]:
    """Versions of what wrote the run. h5py's from its distribution's metadata: the daemon
    (the loop's process) runs experiments and never imports h5py (the writer process does)."""
    from importlib.metadata import version

    import numpy

    return {"rigd_version": __version__, "python": platform.python_version(),
            "numpy": numpy.__version__, "h5py": version("h5py")}


def check_folder_name(path: str) -> None:
    """InputError when ``path`` holds a character that would make it read as something else
    in a listing or a terminal: a newline or other control character, a bidirectional
    override or another invisible format character (Unicode categories Cc, Cf, Zl, Zp, Co,
    Cs)."""
    import unicodedata

    for i, ch in enumerate(path):
        cat = unicodedata.category(ch)
        if cat in ("Cc", "Cf", "Zl", "Zp", "Co", "Cs"):
            what = "a control character" if cat == "Cc" else \
                "a bidirectional or invisible format character" if cat == "Cf" else \
                "a line or paragraph separator" if cat in ("Zl", "Zp") else \
                "an unassigned or private-use character"
            raise InputError(f"run folder name has {what} (U+{ord(ch):04X} at position {i}): "
                             "refused; use letters, digits, '-', '_' and '.'",
                             repr(path)[:120])


def new_run_dir(out: str | Path | None, name: str, root: str | Path = "runs") -> Path:
    """Create a new, empty run directory.

    ``out`` given: it must not exist (or be an empty directory). Otherwise
    ``root/<UTC time>-<name>`` with a ``-2``, ``-3``... suffix if taken. ``os.mkdir`` is
    atomic, so two runs never share a directory.
    """
    if out is not None:
        p = Path(out)
        check_folder_name(str(p))
        if p.exists():
            if not p.is_dir():
                raise InputError("exists and is not a directory", str(p))
            if any(p.iterdir()):
                raise InputError("run directory exists and is not empty: nothing is ever "
                                 "overwritten, choose a new one", str(p))
            return p
        p.parent.mkdir(parents=True, exist_ok=True)
        try:
            p.mkdir()
        except FileExistsError:
            raise InputError("run directory appeared meanwhile; choose a new one",
                             str(p)) from None
        return p
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    safe = re.sub(r"[^A-Za-z0-9_.\-]+", "_", name)[:60] or "run"
    for i in range(1, 10000):
        p = root / (f"{stamp}-{safe}" + (f"-{i}" if i > 1 else ""))
        try:
            p.mkdir()
            return p
        except FileExistsError:
            continue
    raise InputError("cannot create a new run directory", str(root))  # pragma: no cover


@dataclass
class Manifest:
    """The manifest of one run, kept in memory and written after every change."""

    run_dir: Path
    experiment: dict[str, Any]
    mode: str
    fs_hz: float
    config: dict[str, Any] = field(default_factory=lambda: {"path": None, "sha256": None})
    points: list[dict[str, Any]] = field(default_factory=list)
    files: list[dict[str, Any]] = field(default_factory=list)
    source: str | None = None
    drivers: dict[str, Any] = field(default_factory=dict)
    status: str = "running"
    started: str = field(default_factory=now_iso)
    finished: str | None = None
    message: str = ""
    #: the latched fault that ended the run (seq, code, name, text), None otherwise
    fault: dict[str, Any] | None = None
    #: the process writing the manifest (rigd.owner.this_process)
    owner: dict[str, Any] = field(default_factory=this_process)

    @property
    def path(self) -> Path:
        return self.run_dir / MANIFEST

    @property
    def missing(self) -> list[int]:
        return [p["index"] for p in self.points if p["status"] != "done"]

    def add_point(self, omega_rpm: float | None, p_inj_bar: float | None) -> dict[str, Any]:
        pt = {"index": len(self.points), "omega_rpm": omega_rpm, "p_inj_bar": p_inj_bar,
              "status": "missing", "files": [], "error": None, "started": None,
              "finished": None, "recording": None}
        self.points.append(pt)
        return pt

    def add_file(self, point: dict[str, Any], path: Path, **info: Any) -> None:
        rel = os.path.relpath(path, self.run_dir)
        point["files"].append(rel)
        self.files.append({"path": rel, "point": point["index"], **info})

    def to_dict(self) -> dict[str, Any]:
        return {
            "rigd_manifest": 1,
            "experiment": self.experiment,
            "status": self.status,
            "owner": self.owner,
            "started": self.started,
            "finished": self.finished,
            "host": platform.node(),
            "mode": self.mode,
            "source": self.source,
            "drivers": self.drivers,
            "software": software(),
            "config": self.config,
            "fs_hz": self.fs_hz,
            "points": self.points,
            "files": self.files,
            "missing": self.missing,
            "message": self.message,
            "fault": self.fault,
        }

    @property
    def reserve_path(self) -> Path:
        return self.run_dir / RESERVE

    def reserve(self) -> None:
        """Set :data:`RESERVE_BYTES` aside in the run folder: a disk that fills during the
        run still takes the manifests that list what was kept (see :meth:`write`)."""
        try:
            with open(self.reserve_path, "xb") as fh:
                fh.write(b"\0" * RESERVE_BYTES)
        except OSError:
            pass                     # no reserve: the writes below are tried all the same

    def release(self) -> None:
        """Give the reserve back (the run is over)."""
        self.reserve_path.unlink(missing_ok=True)

    def write(self) -> None:
        """Write ``manifest.json`` atomically (never a half-written manifest); on a full disk
        the reserve is given back and the write tried again."""
        text = json.dumps(self.to_dict(), indent=2, default=str) + "\n"
        try:
            atomic_write_text(self.path, text)
        except OSError as exc:
            if exc.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG) or \
                    not self.reserve_path.exists():
                raise
            self.release()
            atomic_write_text(self.path, text)
