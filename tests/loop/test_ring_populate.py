"""SharedRing.populate: the shared-memory ring's pages are faulted in before the cycles run.

Untouched shmem pages cost the cycle kernel a page fault at its first write to each of them
(one every ~16 frames for the first pass through the ring): the ``loop_compute_us`` p99 went
from 0.7 to 3.2 µs when the ring moved into shared memory. The real-time loop thread's
``mlockall`` populates it; ``populate`` does it where that is not available (and the bench).
"""

from __future__ import annotations

import numpy as np

from rigd.frame import N_REC
from rigd.loop.shared_ring import SharedRing


def _rss_kib(addr: int) -> int:
    """Resident KiB of this process's mapping that holds address ``addr`` (/proc/self/smaps)."""
    inside = False
    with open("/proc/self/smaps") as f:
        for line in f:
            head = line.split(" ", 1)[0]
            if "-" in head and ":" not in head:             # a mapping's header line
                lo, hi = (int(x, 16) for x in head.split("-"))
                inside = lo <= addr < hi
            elif inside and line.startswith("Rss:"):
                return int(line.split()[1])
    raise AssertionError("mapping not found")


def test_populate_faults_every_page_in_and_keeps_the_frames():
    # a real-time loop earlier in this process left mlockall(MCL_FUTURE) in force, under
    # which a new mapping is populated at once: undo it, this test is about populate()
    import ctypes
    import ctypes.util

    ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").munlockall()
    n = 1 << 14                                            # 4 MiB of frames
    ring = SharedRing(n, N_REC, 5000.0)
    ring.ring[:3] = np.arange(3 * N_REC).reshape(3, N_REC)
    before = _rss_kib(ring.ring.ctypes.data)
    size_kib = n * N_REC * 8 // 1024
    assert before < size_kib // 4
    ring.populate()
    assert _rss_kib(ring.ring.ctypes.data) >= size_kib
    np.testing.assert_array_equal(ring.ring[:3], np.arange(3 * N_REC).reshape(3, N_REC))
    assert not ring.ring[3:].any()
