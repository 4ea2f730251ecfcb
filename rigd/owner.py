"""Which process owns a run, whether it still lives, and who holds a file open.

A run's ``manifest.json`` names its owner — the process that writes it (the experiment
process of a daemon-hosted run, or ``rigd experiment`` itself): host name, pid and the
process's start time in clock ticks since boot (``/proc/PID/stat`` field 22), so that a pid
reused by another process after a crash is not taken for the owner. The daemon and
``rigd experiment --lockstep`` read it on start to find runs a dead process left
``running`` (:mod:`rigd.experiments.recovery`). Linux ``/proc`` only; no HDF5, no
experiments here (the loop's process imports this module).
"""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path
from typing import Any

#: the state of a run whose process ended without finishing it (set on recovery)
PROCESS_ENDED = "interrupted (process ended)"

#: largest manifest read while looking for stale runs, bytes
MAX_MANIFEST = 8 << 20


def start_ticks(pid: int) -> int | None:
    """Process ``pid``'s start time (clock ticks since boot), None if it does not exist or
    has ended: a zombie (state ``Z``, killed but not yet reaped by its parent: the moments
    after a crash, while its dead parent's orphans wait for init) writes nothing again."""
    try:
        stat = Path(f"/proc/{int(pid)}/stat").read_text()
    except (OSError, ValueError):
        return None
    try:
        fields = stat.rsplit(")", 1)[1].split()
        if fields[0] in ("Z", "X"):
            return None
        return int(fields[19])
    except (IndexError, ValueError):
        return None


def this_process() -> dict[str, Any]:
    """The owner record of the calling process: ``host``, ``pid``, ``start_ticks``."""
    pid = os.getpid()
    return {"host": platform.node(), "pid": pid, "start_ticks": start_ticks(pid)}


def alive(owner: Any) -> bool:
    """Is the process of ``owner`` (:func:`this_process` as written) still running?

    True for an owner on another host (its runs folder is shared: not ours to judge) or one
    that cannot be read; False for a missing owner (a manifest from before owners were
    written) or a pid that is gone or now belongs to a process started later.
    """
    if not isinstance(owner, dict):
        return False
    if owner.get("host") not in (None, platform.node()):
        return True
    try:
        pid = int(owner["pid"])
    except (KeyError, TypeError, ValueError):
        return False
    now = start_ticks(pid)
    if now is None:
        return False
    want = owner.get("start_ticks")
    return want is None or int(want) == now


def stale_runs(root: str | Path) -> list[Path]:
    """Run folders under ``root`` whose manifest says ``running`` and whose owner is gone
    (cheap: JSON only; the recovery itself reads HDF5 in a helper process)."""
    out: list[Path] = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return out
    for e in entries:
        if not e.is_dir(follow_symlinks=False) or e.name.startswith("."):
            continue
        p = Path(e.path) / "manifest.json"
        try:
            if p.is_symlink() or p.stat().st_size > MAX_MANIFEST:
                continue
            man = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(man, dict) and man.get("status") == "running" \
                and not alive(man.get("owner")):
            out.append(Path(e.path))
    return sorted(out)


def holders(path: str | Path) -> list[int]:
    """Pids of the processes holding ``path`` open (those whose ``/proc/PID/fd`` we may
    read: the same user's, or all for root)."""
    try:
        target = os.path.realpath(path)
    except OSError:
        return []
    me = os.getpid()
    out = []
    for d in os.scandir("/proc"):
        if not d.name.isdigit() or int(d.name) == me:
            continue
        try:
            fds = os.scandir(f"/proc/{d.name}/fd")
        except OSError:
            continue
        with fds:
            for fd in fds:
                try:
                    if os.readlink(fd.path) == target:
                        out.append(int(d.name))
                        break
                except OSError:
                    continue
    return out
