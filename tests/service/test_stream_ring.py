"""The shared ring read by another thread/process: torn-read check, min/max decimation.

The torn-read test races a real writer: a numba kernel compiled ``nogil`` writes frames into a
small shared ring column by column on one core while this thread reads on the other, so rows
really are overwritten while they are being copied.
"""

import threading
import time

import numpy as np
import pytest
from numba import njit

from rigd.loop.shared_ring import H_W, H_WALL, RingReader, SharedRing
from rigd.service.stream import decimate, outward

COLS = 8


@njit(nogil=True, cache=True)
def _write_frames(ring, hdr, start, count):
    """Write frames ``start .. start+count-1``: every column of frame f holds f (written one
    column at a time, like the cycle kernel), then publish the count."""
    n = ring.shape[0]
    for f in range(start, start + count):
        r = f % n
        for c in range(ring.shape[1]):
            ring[r, c] = f
        hdr[H_W] = f + 1
    return start + count


def _consistent(first, frames):
    want = np.arange(first, first + len(frames), dtype=float)[:, None]
    return bool((frames == want).all())


def test_reader_never_returns_a_torn_frame_while_a_writer_races_it():
    ring = SharedRing(64, COLS, fs=5000.0)
    reader = RingReader(ring.handle())
    assert reader.fs == 5000.0 and reader.n == 64
    with pytest.raises(ValueError):           # the reader's map is read-only
        reader.ring[0, 0] = 1.0
    stop = threading.Event()
    written = [0]

    def writer():
        f = 0
        while not stop.is_set():
            f = _write_frames(ring.ring, ring.hdr, f, 2000)
        written[0] = f

    _write_frames(ring.ring, ring.hdr, 0, 1)     # compiled before the race starts
    ring.hdr[H_W] = 0
    t = threading.Thread(target=writer, daemon=True)
    t.start()
    reads = naive_torn = 0
    end = time.monotonic() + 120.0
    try:
        # until the check has discarded rows many times, and a copy *without* it was seen torn
        while (reader.torn < 100 or naive_torn == 0 or reads < 1000) and \
                time.monotonic() < end:
            first, frames, _ = reader.recent(0, 63)   # 63 of 64 rows: the writer laps us
            reads += 1
            assert _consistent(first, frames), (first, frames[:, 0])
            w = int(ring.hdr[H_W])                    # the same copy, no second look
            if w >= 63:
                a = (w - 63) % 64
                raw = np.concatenate((reader.ring[a:], reader.ring[:a]))[:63]
                if not _consistent(w - 63, raw):
                    naive_torn += 1
    finally:
        stop.set()
        t.join(30)
    assert reader.torn >= 100, f"writer never overtook the reader in {reads} reads"
    assert naive_torn > 0, "a copy without the check was never torn: the race did not happen"
    assert written[0] > 64


def test_recent_returns_only_new_frames_and_counts_what_it_cannot_cover():
    ring = SharedRing(1024, COLS, fs=1000.0)
    reader = RingReader(ring.handle())
    assert reader.recent(0, 100)[1].shape == (0, COLS)
    _write_frames(ring.ring, ring.hdr, 0, 300)
    first, frames, _ = reader.recent(0, 100)
    assert (first, len(frames)) == (200, 100)         # the newest 100
    assert _consistent(first, frames)
    first, frames, _ = reader.recent(300, 100)
    assert len(frames) == 0                           # nothing new
    _write_frames(ring.ring, ring.hdr, 300, 5)
    first, frames, _ = reader.recent(300, 100)
    assert (first, len(frames)) == (300, 5) and _consistent(first, frames)
    # a wrap around the end of the ring
    _write_frames(ring.ring, ring.hdr, 305, 1000)
    first, frames, _ = reader.recent(1200, 500)
    assert (first, len(frames)) == (1200, 105) and _consistent(first, frames)


def test_publish_stores_the_wall_time_before_the_count():
    ring = SharedRing(16, COLS)
    before = time.time_ns()
    ring.publish(5)
    assert int(ring.hdr[H_W]) == 5
    assert before <= int(ring.hdr[H_WALL]) <= time.time_ns()


@pytest.mark.parametrize("n,points", [(1, 200), (7, 3), (100, 100), (1000, 7), (5, 200)])
def test_decimate_brackets_every_frame_and_keeps_spikes(n, points):
    rng = np.random.default_rng(n)
    x = rng.normal(size=(n, 3))
    x[n // 2, 1] = 50.0                                 # a one-frame spike
    lo, hi, starts = decimate(x, points)
    b = min(points, n)
    assert lo.shape == hi.shape == (b, 3) and len(starts) == b
    assert starts[0] == 0 and np.all(np.diff(starts) >= 1)
    ends = np.append(starts[1:], n)
    for i in range(b):
        seg = x[starts[i]:ends[i]]
        np.testing.assert_array_equal(lo[i], seg.min(axis=0))
        np.testing.assert_array_equal(hi[i], seg.max(axis=0))
    assert hi[:, 1].max() == 50.0
    sizes = ends - starts
    assert sizes.max() - sizes.min() <= 1              # buckets of n//b or n//b + 1 frames


def test_outward_rounding_keeps_every_sample_inside_and_is_short():
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.normal(scale=s, size=2000) for s in (1e-6, 1e-3, 1.0, 1e4)])
    x = np.concatenate([x, np.arange(-3, 3) * 1e-5, [1e-5 * 7 - 1e-21, 4.3e9, 0.0]])
    lo, hi = outward(x, x)
    assert np.all(lo <= x) and np.all(hi >= x)
    assert np.all(x - lo <= 1e-5 * (1 + 1e-9) + 1e-12 * abs(x))
    assert np.all(hi - x <= 1e-5 * (1 + 1e-9) + 1e-12 * abs(x))
    assert max(len(repr(v)) for v in lo.tolist()) <= 16      # not 17-digit doubles
    nan_lo, nan_hi = outward(np.array([np.nan]), np.array([np.nan]))
    assert np.isnan(nan_lo[0]) and np.isnan(nan_hi[0])



def test_an_update_before_the_first_timed_cycle_is_strict_json():
    """Right after start the loop has timed no cycle: the timing percentiles are NaN. The
    update must still be one strict-JSON line (NaN -> null, rigd.plain's policy); a NaN once
    made the push stop and the subscriber wait for a time-out (CI, stop 18)."""
    import json

    from rigd.frame import N_REC
    from rigd.loop.layout import H_NB
    from rigd.loop.timing import summary
    from rigd.service.stream import StreamHub

    ring = SharedRing(1024, N_REC, fs=5000.0)
    _write_frames(ring.ring, ring.hdr, 0, 200)
    timing = summary(np.zeros((2, H_NB + 3), dtype=np.int64))
    assert np.isnan(timing["compute_us"]["p99"])            # what the daemon publishes
    snap = {"v": 1, "status": {"seq": 200, "running": True, "fault": {"code": 0}},
            "timing": timing}
    hub = StreamHub(RingReader(ring.handle()), lambda: snap)
    _, sub = hub.subscribe(50, 8, ["seq", "t"])
    line = sub.update()
    body = json.loads(line)["stream"]                         # strict JSON parses it
    assert body["status"]["compute_us"]["p99"] is None
    assert body["status"]["lateness_us"]["max"] is None
    assert body["status"]["cycle"] == 200 and body["n"] > 0
