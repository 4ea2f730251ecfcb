"""The live stream (``stream.subscribe``), built in the socket process from the shared ring.

A client sends ``{"id": 1, "cmd": "stream.subscribe", "rate_hz": 50, "points": 200,
"channels": null}``; the reply's ``result`` is ``{"fs_hz", "rate_hz", "points", "channels"}``
and then, ``rate_hz`` times a second, the socket process pushes one line ``{"stream": {...}}``
on that connection (shape: :func:`Subscription.update`, docs/service.md "Live stream").

Where the data comes from: the recorder's ring buffer is shared memory
(:mod:`rigd.loop.shared_ring`) that this process maps read-only; each update copies the frames
published since the previous one (torn-read checked) and reduces them by **min/max
decimation**: the ``n`` new frames are split into ``min(points, n)`` consecutive buckets and
each bucket sends its minimum and maximum per channel, so a spike of one frame is never lost
from the picture however few points are sent. Minima are rounded down and maxima up to
:data:`QUANTUM` (:func:`outward`): the band still contains every sample, in half the bytes.
The loop thread does nothing for the stream (it stores the published count and a wall-clock
time after each kernel call).

The cheap status fields come from the snapshot the daemon publishes anyway (25 Hz).
"""

from __future__ import annotations

import json
import time
from typing import Any

import numpy as np

from rigd.frame import REC, RECORD_NAMES
from rigd.loop.shared_ring import RingReader
from rigd.plain import plain

#: one update covers at most this much loop time; older frames are counted in ``dropped``.
#: Ten seconds (of a ring of tens of seconds) so that a socket process starved on a busy
#: machine (it runs niced) catches up instead of dropping frames the ring still holds.
MAX_BACK_S = 10.0
#: sent minima are rounded down and maxima up to a multiple of this (in each channel's unit:
#: 10 pm for µm, 10 µV for V): :func:`outward`
QUANTUM = 1e-5


def decimate(frames: np.ndarray, points: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Min/max decimation of ``frames`` into at most ``points`` consecutive buckets.

    Parameters
    ----------
    frames : numpy.ndarray
        ``(n, c)``, oldest first, ``n >= 1``.
    points : int
        Most buckets.

    Returns
    -------
    lo, hi : numpy.ndarray
        ``(b, c)`` per-bucket minimum and maximum, ``b = min(points, n)``; NaN where a bucket
        holds a NaN (a NaN sensor value is shown, not hidden).
    starts : numpy.ndarray
        ``(b,)`` index of each bucket's first frame.
    """
    n = len(frames)
    b = min(int(points), n)
    starts = (np.arange(b) * n) // b
    lo = np.minimum.reduceat(frames, starts, axis=0)
    hi = np.maximum.reduceat(frames, starts, axis=0)
    return lo, hi, starts


def outward(lo: np.ndarray, hi: np.ndarray,
            quantum: float = QUANTUM) -> tuple[np.ndarray, np.ndarray]:
    """Round minima down and maxima up to multiples of ``quantum`` (``1 / quantum`` must be
    an integer, e.g. 1e-5).

    The rounded ``lo`` is never above the true minimum nor ``hi`` below the true maximum (so
    the sent band still contains every sample) and neither moves by more than ``quantum``;
    ``k / (1 / quantum)`` is the double nearest the decimal ``k · quantum``, so JSON writes it
    with few digits (about half the bytes and half the encoding time of full precision).
    """
    scale = round(1.0 / quantum)
    with np.errstate(invalid="ignore"):
        a = np.floor(lo * scale) / scale
        a = np.where(a > lo, (np.floor(lo * scale) - 1.0) / scale, a)
        b = np.ceil(hi * scale) / scale
        b = np.where(b < hi, (np.ceil(hi * scale) + 1.0) / scale, b)
    return a, b


def _floats(a: np.ndarray) -> list:
    """A list for JSON: non-finite values become None (strict JSON)."""
    out = a.tolist()
    if not np.isfinite(a).all():
        out = [v if np.isfinite(v) else None for v in out]
    return out


class Subscription:
    """One client's subscription: its rate, points, channels and read position.

    Parameters
    ----------
    reader : RingReader
    rate_hz : float
        Updates per second.
    points : int
        Most buckets per channel per update.
    channels : list of str
        Record channels sent (validated names).
    status : callable
        ``() -> dict``: the cheap status fields (:meth:`StreamHub.status`).
    """

    def __init__(self, reader: RingReader, rate_hz: float, points: int, channels: list[str],
                 status) -> None:
        self.reader = reader
        self.period = 1.0 / float(rate_hz)
        self.points = int(points)
        self.channels = list(channels)
        self._cols = np.array([REC[c] for c in self.channels], dtype=np.intp)
        self._status = status
        fs = reader.fs or 1.0
        self.max_frames = max(1, int(fs * MAX_BACK_S))
        # the first update covers one period before the subscription
        self.next_frame = max(0, reader.published - max(1, int(fs * self.period)))
        self.next_due = time.monotonic() + self.period
        self.sent = 0

    def update(self, now: float | None = None) -> bytes | None:
        """The next update line, or None when nothing new was published (loop stopped).

        The line is ``{"stream": {...}}`` with ``seq``, ``t_s``, ``wall_ns``, ``n``,
        ``dropped``, ``t`` (loop time of each bucket's first frame), ``min``, ``max`` and
        ``status`` (docs/service.md).
        """
        now = time.monotonic() if now is None else now
        self.next_due = max(self.next_due + self.period, now)   # no burst after a stall
        first, frames, wall = self.reader.recent(self.next_frame, self.max_frames)
        if len(frames) == 0:
            return None
        dropped = first - self.next_frame
        self.next_frame = first + len(frames)
        lo, hi, starts = decimate(frames[:, self._cols], self.points)
        lo, hi = outward(lo, hi)
        newest = frames[-1]
        body = {"seq": int(newest[REC["seq"]]), "t_s": float(newest[REC["t"]]),
                "wall_ns": wall, "n": len(frames), "dropped": int(dropped),
                "t": frames[starts, REC["t"]].tolist(),
                "min": {c: _floats(lo[:, i]) for i, c in enumerate(self.channels)},
                "max": {c: _floats(hi[:, i]) for i, c in enumerate(self.channels)},
                "status": self._status()}
        self.sent += 1
        return (json.dumps({"stream": body}, separators=(",", ":"), allow_nan=False)
                + "\n").encode()


class StreamHub:
    """The stream side of the socket process: the ring reader and the status fields.

    Parameters
    ----------
    reader : RingReader or None
        None when the daemon shares no ring (then ``stream.subscribe`` is refused).
    snapshot : callable
        ``() -> dict``: the latest snapshot the daemon published (status, timing, ...).
    """

    def __init__(self, reader: RingReader | None, snapshot) -> None:
        self.reader = reader
        self._snapshot = snapshot
        self._cache: tuple[int, dict] = (-2, {})

    def subscribe(self, rate_hz: float, points: int,
                  channels: list[str] | None) -> tuple[dict, Subscription]:
        """A new subscription and the ``result`` of the ok reply."""
        if self.reader is None:
            raise LookupError("stream.subscribe: this daemon shares no recording ring "
                              "(its log at start says why)")
        names = list(channels) if channels else list(RECORD_NAMES)
        sub = Subscription(self.reader, rate_hz, points, names, self.status)
        return {"fs_hz": self.reader.fs, "rate_hz": float(rate_hz), "points": int(points),
                "channels": names}, sub

    def status(self) -> dict[str, Any]:
        """The cheap status fields, recomputed once per snapshot version (non-finite -> None)."""
        snap = self._snapshot()
        v = snap.get("v", -1)
        if self._cache[0] == v:
            return self._cache[1]
        st = snap.get("status", {}) or {}
        tm = snap.get("timing", {}) or {}
        f = st.get("fault", {}) or {}
        ctrl = st.get("controller", {}) or {}
        last = st.get("last_frame", {}) or {}
        out = {"cycle": st.get("seq"), "running": st.get("running"), "clock": st.get("clock"),
               "k_on": bool(ctrl.get("enabled")), "k_requested": bool(ctrl.get("requested")),
               "k_loaded": bool(ctrl.get("loaded")),
               "fault": {"code": f.get("code", 0), "name": f.get("name", "none"),
                         "text": f.get("text", ""), "seq": f.get("seq")},
               "omega_rpm": _finite(last.get("omega_rpm")),
               "p_inj_bar": _finite(last.get("p_inj_bar")),
               "set_point": st.get("set_point"),
               "misses": tm.get("overruns"), "miss_fraction": _finite(tm.get("miss_fraction")),
               "cycles_timed": tm.get("cycles"),
               "compute_us": tm.get("compute_us"), "lateness_us": tm.get("lateness_us"),
               "experiment": (snap.get("experiment") or {}).get("state")}
        # the one NaN policy (rigd.plain): before the loop has timed a cycle its percentiles
        # are NaN, and a NaN would make the strict-JSON update line fail
        out = plain(out)
        self._cache = (v, out)
        return out


def _finite(x):
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if np.isfinite(x) else None
