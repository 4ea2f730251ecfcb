"""Timing statistics from the preallocated per-cycle histograms (no growing lists).

The real-time cycle kernel adds every cycle's compute time (read -> write, drivers included)
and wake-up lateness (wake-up time - deadline) to an int64 histogram of
:data:`~rigd.loop.layout.H_BIN_NS` ns bins (:func:`rigd.loop.cycle.rt_cycle`). This module
turns it into percentiles; values are bin upper edges (conservative), in µs.
"""

from __future__ import annotations

import numpy as np

from rigd.loop.layout import H_BIN_NS, H_COMPUTE, H_COUNT, H_LATE, H_MAX, H_NB

QUANTILES = (("p50", 0.50), ("p99", 0.99), ("p999", 0.999))


def percentiles(hist: np.ndarray, row: int) -> dict[str, float]:
    """``{"p50", "p99", "p999", "max", "n"}`` of one histogram row, µs (n: samples)."""
    h = np.array(hist[row])           # snapshot: the loop keeps adding
    n = int(h[H_COUNT])
    out: dict[str, float] = {"n": n}
    if n == 0:
        out.update({k: float("nan") for k, _ in QUANTILES})
        out["max"] = float("nan")
        return out
    cum = np.cumsum(h[:H_NB + 1])     # last bin: overflow
    mx = h[H_MAX] / 1000.0
    for key, q in QUANTILES:
        b = int(np.searchsorted(cum, q * n, side="left"))
        out[key] = round(min((b + 1) * H_BIN_NS / 1000.0, mx), 3) if b < H_NB else round(mx, 3)
    out["max"] = round(mx, 3)
    return out


def coarse(hist: np.ndarray, row: int, nbins: int = 32) -> dict:
    """The histogram of one row in at most ``nbins`` equal bins, for display.

    Returns
    -------
    dict
        ``{"edges_us": [nbins + 1 bin edges, µs], "counts": [nbins ints], "overflow": int}``;
        the bins cover 0 up to the highest occupied fine bin (``H_BIN_NS`` each), the
        samples beyond the fine range are in ``overflow``. Empty lists before any sample.
    """
    h = np.array(hist[row])           # snapshot: the loop keeps adding
    fine = h[:H_NB]
    nz = np.flatnonzero(fine)
    if nz.size == 0:
        return {"edges_us": [], "counts": [], "overflow": int(h[H_NB])}
    width = -(-(int(nz[-1]) + 1) // nbins)            # fine bins per coarse bin (ceil)
    padded = np.zeros(width * nbins, dtype=np.int64)
    top = min(width * nbins, H_NB)
    padded[:top] = fine[:top]
    counts = padded.reshape(nbins, width).sum(axis=1)
    edges = np.arange(nbins + 1) * (width * H_BIN_NS / 1000.0)
    return {"edges_us": [round(float(e), 3) for e in edges],
            "counts": [int(c) for c in counts], "overflow": int(h[H_NB])}


def summary(hist: np.ndarray, *, overruns: int = 0, skipped: int = 0,
            cycles: int | None = None) -> dict:
    """Timing summary as served by ``ControlLoop.timing()`` on the real-time clock."""
    comp = percentiles(hist, H_COMPUTE)
    late = percentiles(hist, H_LATE)
    n = int(cycles if cycles is not None else late["n"])
    return {
        "clock": "realtime",
        "cycles": n,
        "compute_us": {k: v for k, v in comp.items() if k != "n"},
        "lateness_us": {k: v for k, v in late.items() if k != "n"},
        "overruns": int(overruns),
        "skipped_periods": int(skipped),
        # periods without an on-time cycle (a late cycle, or no cycle at all: skipped) over
        # the periods elapsed (docs/loop.md): a stalled loop raises it
        "miss_fraction": miss_fraction(overruns, skipped, n),
        # late cycles over the cycles run (the former miss_fraction: blind to skipped periods)
        "overrun_fraction": (overruns / n) if n else 0.0,
        "histogram_us": {"compute": coarse(hist, H_COMPUTE), "lateness": coarse(hist, H_LATE)},
    }


def miss_fraction(overruns: int, skipped: int, cycles: int) -> float:
    """Periods missed over periods elapsed: ``(overruns + skipped) / (cycles + skipped)``.

    A late cycle (overrun) missed its period; a skipped period had no cycle at all. Both count,
    so a loop that stood still for a while shows it (overruns / cycles alone *fell* then)."""
    periods = cycles + skipped
    return (overruns + skipped) / periods if periods else 0.0


def format_summary(t: dict) -> str:
    """A few human-readable lines for the end of ``rigd run``."""
    if t.get("clock") == "lockstep":
        return (f"lock-step: {t['cycles']} cycles in {t['wall_s']:.3f} s = "
                f"{t['cycles_per_s']:,.0f} cycles/s ({t['realtime_factor']:.1f}x real time)")
    c, lt = t["compute_us"], t["lateness_us"]
    return (f"real-time: {t['cycles']} cycles, overruns {t['overruns']} "
            f"(miss fraction {t['miss_fraction']:.2e}), skipped periods {t['skipped_periods']}\n"
            f"  compute  us: p50 {c['p50']}  p99 {c['p99']}  p99.9 {c['p999']}  max {c['max']}\n"
            f"  lateness us: p50 {lt['p50']}  p99 {lt['p99']}  p99.9 {lt['p999']}  max {lt['max']}")
