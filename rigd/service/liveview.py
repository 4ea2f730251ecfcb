"""``status`` and ``ping`` as the loop is *now*: the daemon's snapshot overlaid with its SAFE word.

The socket process answers queries from the daemon's snapshot (published at 25 Hz and after
each command). A snapshot can be older than what a client already saw: ``rigd ctl safe``
writes the SAFE word itself and gets the cycle it latched at from the kernel, and a snapshot
published before that cycle said "no fault" (measured: `status` right after a SAFE showed seq 0
and no fault, and lagged up to a second under load); and a loop that stands still publishes
nothing new at all (its snapshot kept saying `running, no fault` with a frozen counter). The
SAFE word (:mod:`rigd.loop.safeword`) is written by the kernel every cycle — the cycle
running, the fault in force and when it latched, the time of the cycle — so the socket process
overlays it on the snapshot (:func:`rigd.loop.safeword.live`):

* ``seq`` is the word's when newer; ``fault`` is the kernel's (a fault the snapshot does not
  know yet is shown with its generic text);
* ``age_s`` is the time since the latest cycle, ``stalled`` whether it is older than the stall
  bound (``stall_bound_s``), ``stall`` the latest stall (cycle, length, words); while the loop
  stands and no fault is latched, ``fault`` is the ``loop_stall`` the watchdog latched (taken
  by the loop's next cycle);
* ``running`` is true when the word shows fresh cycles after a snapshot that said it was
  not (a snapshot from before the loop's first cycle, still held when READY=1 went out);
* ``ping`` answers ``pong`` only while the loop cycles.
"""

from __future__ import annotations

from typing import Any

from rigd.loop import faults as FC
from rigd.loop.safeword import live


def status(st: dict[str, Any], w) -> dict[str, Any]:
    """The snapshot's ``status`` dict ``st`` overlaid with the word ``w`` (module docstring)."""
    lv = live(w)
    out = dict(st)
    snap_seq = int(st.get("seq") or 0)
    if lv["seq"] >= snap_seq:        # the word is at least as new (always, once it cycles)
        out["seq"] = lv["seq"]
        fs = st.get("fs_hz")
        if fs:
            out["t_s"] = lv["seq"] / float(fs)
        f = st.get("fault") or {}
        code, fseq = lv["fault"]["code"], lv["fault"]["seq"]
        if code != int(f.get("code") or 0) or (code and fseq != f.get("seq")):
            out["fault"] = _fault(code, fseq, lv)
    if st.get("running") is False and _started_since(st, lv):
        out["running"] = True        # a snapshot from before the first cycle
    out["age_s"] = lv["age_s"]
    out["stalled"] = lv["stalled"]
    out["stall_bound_s"] = lv["stall_bound_s"]
    out["stall"] = lv["stall"]
    if lv["stalled"] and int((out.get("fault") or {}).get("code") or 0) == 0:
        out["fault"] = {"code": FC.LOOP_STALL, "name": FC.fault_name(FC.LOOP_STALL),
                        "text": lv["stall"]["text"] + " (latched; the safe state holds from "
                                "the loop's next cycle)", "seq": lv["stall"]["cycle"]}
    if int((out.get("fault") or {}).get("code") or 0) and isinstance(out.get("controller"),
                                                                      dict):
        out["controller"] = {**out["controller"], "enabled": False}
    return out


def _fault(code: int, seq: int, lv: dict) -> dict[str, Any]:
    if not code:
        return {"code": 0, "name": "none", "text": "", "seq": None}
    text = (lv["stall"]["text"] if code == FC.LOOP_STALL and lv["stall"] is not None
            else FC.fault_text(code))
    return {"code": code, "name": FC.fault_name(code), "text": text, "seq": seq}


def _started_since(st: dict[str, Any], lv: dict | None) -> bool:
    """Has the loop cycled since the snapshot ``st`` said it was not running? A snapshot
    taken before the loop's first cycle says ``running: false``, and the socket process can
    still hold it when READY=1 is sent (the next one comes within the publish period, later
    under load): the word's cycles after the snapshot's ``seq``, fresh, say it runs."""
    return (lv is not None and not lv["stalled"] and lv["age_s"] is not None
            and not st.get("loop_error") and lv["seq"] > int(st.get("seq") or 0))


def not_cycling(st: dict[str, Any], w) -> str | None:
    """Why ``ping`` must not answer alive (the loop stands or stopped), or None."""
    lv = live(w) if w is not None else None
    if lv is not None and lv["stalled"]:
        return (f"the daemon answers but its loop is not cycling: no cycle for "
                f"{lv['age_s']:.3f} s after cycle {lv['seq']} (stall bound "
                f"{lv['stall_bound_s'] * 1e3:g} ms); loop_stall latched")
    if st and st.get("running") is False and not _started_since(st, lv):
        why = st.get("loop_error") or "stopped"
        return f"the daemon answers but its loop is not running ({why})"
    return None
