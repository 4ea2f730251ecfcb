"""What an incomplete recording holds, and marking it so (HDF5: run in a helper process).

A record cut short (the writing process killed, a full disk, a fault, SIGINT) is kept: its
root attributes say ``complete = False``, ``incomplete_reason`` and ``n_frames`` (the frames
on disk). :mod:`rigd.recording.h5sink` writes them from the file's creation on; here the
reason is made precise after the fact (:func:`mark_incomplete`) when the file can be opened
for writing — a file whose SWMR writer was killed keeps its "open for writing" flag and is
only ever read (``swmr=True``), with the attributes its writer last flushed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

#: root attributes copied into a recovered file's manifest entry
META_KEYS = ("kind", "point", "omega_rpm", "p_inj_bar", "controller_on", "repeat", "axis")


def _plain(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and v != v:
        return None
    return v if isinstance(v, (bool, int, float, str)) or v is None else str(v)


def describe(path: str | Path) -> dict[str, Any]:
    """``readable``, ``n_frames`` (frames on disk), ``complete``, ``incomplete_reason``,
    ``fs`` and ``meta`` (:data:`META_KEYS`) of a recording; ``error`` when unreadable."""
    try:
        with h5py.File(path, "r", libver="latest", swmr=True) as f:
            n = int(f["frames"].shape[0])
            a = f.attrs
            return {"readable": True, "n_frames": n, "fs": _plain(a.get("fs")),
                    "complete": _plain(a.get("complete")),
                    "incomplete_reason": _plain(a.get("incomplete_reason")),
                    "meta": {k: _plain(a[k]) for k in META_KEYS if k in a}}
    except (OSError, KeyError, ValueError) as exc:
        return {"readable": False, "n_frames": None, "error": str(exc).splitlines()[0][:200]}


def mark_incomplete(path: str | Path, why: str) -> dict[str, Any]:
    """Mark ``path`` incomplete with ``why`` and its frames on disk (when it can be opened for
    writing); :func:`describe` of it afterwards, with ``marked`` (bool)."""
    info = describe(path)
    marked = False
    if info["readable"]:
        try:
            with h5py.File(path, "r+", libver="latest") as f:
                f.attrs["complete"] = False
                f.attrs["incomplete_reason"] = str(why)
                f.attrs["n_frames"] = np.int64(f["frames"].shape[0])
            marked = True
            info = describe(path)
        except OSError:
            pass        # its writer was killed: read-only, with what it last flushed
    info["marked"] = marked
    return info
