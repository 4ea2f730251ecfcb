"""Recovery on start: runs a dead process left ``running`` are closed, their records kept.

As a database replays its journal on start, the daemon (and ``rigd experiment`` in-process)
looks for run folders whose ``manifest.json`` still says ``running`` while the process that
wrote it is gone (:func:`rigd.owner.stale_runs`: host, pid and start time). For each:

* every ``.part`` record (the one the point's ``recording`` names, and any other left in the
  folder) is checked readable (h5py, SWMR), renamed to its final name (never over a file)
  and listed in ``files`` with ``complete: false``, ``incomplete_reason`` and ``n_frames``
  (the frames on disk); the file itself is marked so where it can be opened for writing
  (:func:`rigd.recording.incomplete.mark_incomplete`). A file its writer closed with every
  expected frame (``complete`` true) is listed as it is; an unreadable one stays as it is,
  listed with ``readable: false``. Nothing is deleted;
* the points it was running become ``missing``; the run's state becomes
  ``interrupted (process ended)`` with a message naming what was kept.

HDF5 is read here: the daemon runs :func:`recover_runs` in a helper process (by module
name), never in the loop's process.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from rigd.data.manifest import MANIFEST
from rigd.experiments.manifest import RESERVE, now_iso
from rigd.fileio import atomic_write_text, rename_new
from rigd.owner import PROCESS_ENDED, alive, holders, stale_runs

#: longest wait for a process that still holds a ``.part`` open to let go of it, s (the
#: daemon's writer closes its files as soon as the daemon is gone)
HELD_WAIT_S = 20.0


def _final_name(part: Path) -> Path:
    name = part.name.removesuffix(".part")
    if not name.endswith((".h5", ".hdf5")):
        name = name.replace(".h5.", "_") + ".h5"     # an impact's wait: X.h5.wait -> X_wait.h5
    return part.with_name(name)


def _point_of(man: dict[str, Any], part: Path, meta: dict[str, Any]) -> dict[str, Any] | None:
    for p in man.get("points") or []:
        if p.get("recording") == part.name:
            return p
    idx = meta.get("point")
    for p in man.get("points") or []:
        if idx is not None and p.get("index") == idx:
            return p
    return None


def recover_run(run_dir: str | Path) -> dict[str, Any]:
    """Recover one run folder (see module docstring); ``{"run_dir", "status", "message",
    "files"}`` (``status`` unchanged and ``skipped`` set when it is not recoverable now)."""
    from rigd.recording.incomplete import describe, mark_incomplete

    rd = Path(run_dir)
    path = rd / MANIFEST
    man = json.loads(path.read_text(encoding="utf-8"))
    out: dict[str, Any] = {"run_dir": str(rd), "files": []}
    if man.get("status") != "running" or alive(man.get("owner")):
        return {**out, "status": man.get("status"), "skipped": "not a dead process's run"}
    owner = man.get("owner") or {}
    why = (f"the process running the experiment (pid {owner.get('pid', '?')}) ended before "
           "the record's end; recovered on the next start")
    parts = {rd / p["recording"] for p in man.get("points") or [] if p.get("recording")}
    parts |= set(rd.glob("*.part"))
    parts = {p for p in parts if p.exists() and p.parent == rd}
    end = time.monotonic() + HELD_WAIT_S
    for part in sorted(parts):
        while holders(part):
            if time.monotonic() > end:
                return {**out, "status": "running",
                        "skipped": f"{part.name} is still held open by pid {holders(part)}"}
            time.sleep(0.1)
    kept, names = [], []
    for part in sorted(parts):
        final = _final_name(part)
        try:
            rename_new(part, final)
        except FileExistsError:
            final = part
        names.append(final.name)
        info = describe(final)
        whole = info.get("complete") is True       # closed by its writer with every frame
        if not whole:
            info = mark_incomplete(final, why)
        meta = info.get("meta") or {}
        pt = _point_of(man, part, meta)
        entry = {"path": final.name, "point": pt["index"] if pt else meta.get("point"),
                 **{k: v for k, v in meta.items() if k != "point"},
                 "n_frames": info.get("n_frames")}
        if not whole:
            entry.update(complete=False, incomplete_reason=info.get("incomplete_reason") or why)
        if not info.get("readable"):
            entry["readable"] = False
            entry["error"] = info.get("error")
        man.setdefault("files", []).append(entry)
        if pt is not None:
            pt.setdefault("files", []).append(final.name)
            pt["recording"] = None
        fs = info.get("fs")
        secs = (f", {info['n_frames'] / fs:.1f} s" if info.get("n_frames") is not None
                and isinstance(fs, (int, float)) and fs > 0 else "")
        kept.append(f"{final.name} ({info.get('n_frames')} frames{secs}"
                    f"{'' if info.get('readable') else ', unreadable'}"
                    f"{', whole' if whole else ''})")
    for p in man.get("points") or []:
        if p.get("status") == "running":
            p.update(status="missing", error=why, finished=None)
        p["recording"] = None
    done = sum(p.get("status") == "done" for p in man.get("points") or [])
    man["missing"] = [p["index"] for p in man.get("points") or [] if p.get("status") != "done"]
    man["status"] = PROCESS_ENDED
    man["finished"] = man.get("finished") or now_iso()
    man["recovered"] = now_iso()
    man["message"] = (f"{why}; {done} of {len(man.get('points') or [])} point(s) done; "
                      + (f"records kept: {', '.join(kept)}" if kept
                         else "no record was being written"))
    (rd / RESERVE).unlink(missing_ok=True)       # its space set aside for the manifest
    atomic_write_text(path, json.dumps(man, indent=2, default=str) + "\n")
    return {**out, "status": PROCESS_ENDED, "message": man["message"],
            "files": names}


def recover_runs(root: str | Path) -> list[dict[str, Any]]:
    """:func:`recover_run` of every stale run under ``root``; their summaries."""
    out = []
    for rd in stale_runs(root):
        try:
            out.append(recover_run(rd))
        except Exception as exc:  # noqa: BLE001 - one bad folder never stops the others
            out.append({"run_dir": str(rd), "status": "running",
                        "skipped": f"recovery failed: {type(exc).__name__}: {exc}"})
    return out
