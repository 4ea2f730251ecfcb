"""The coarse cycle-time histogram served by ``timing`` (the console's histogram panel)."""

import numpy as np

from rigd.loop.layout import H_BIN_NS, H_COMPUTE, H_COUNT, H_LATE, H_NB
from rigd.loop.timing import coarse, summary


def _hist(samples_ns, overflow=0):
    h = np.zeros((2, H_NB + 3), dtype=np.int64)
    for v in samples_ns:
        h[H_COMPUTE, min(int(v // H_BIN_NS), H_NB)] += 1
    h[H_COMPUTE, H_NB] += overflow
    h[H_COMPUTE, H_COUNT] = len(samples_ns) + overflow
    return h


def test_coarse_keeps_every_sample_and_its_place():
    rng = np.random.default_rng(3)
    v = rng.gamma(4.0, 3000.0, 5000)          # ns, ~12 µs typical, a tail
    h = _hist(v, overflow=7)
    c = coarse(h, H_COMPUTE, nbins=32)
    assert len(c["counts"]) == 32 and len(c["edges_us"]) == 33
    assert sum(c["counts"]) == 5000 and c["overflow"] == 7
    e = np.array(c["edges_us"])
    assert e[0] == 0 and np.all(np.diff(e) > 0)
    assert e[-1] * 1000 >= v.max()            # the bins reach the slowest cycle
    # each coarse count equals the samples whose time falls in its bin (bin edges in µs)
    fine_us = (v // H_BIN_NS) * H_BIN_NS / 1000.0
    want, _ = np.histogram(fine_us, bins=e)
    np.testing.assert_array_equal(c["counts"], want)


def test_coarse_is_empty_before_any_sample_and_summary_carries_both_rows():
    h = np.zeros((2, H_NB + 3), dtype=np.int64)
    assert coarse(h, H_LATE) == {"edges_us": [], "counts": [], "overflow": 0}
    s = summary(_hist([10_000, 20_000]), overruns=0, cycles=2)
    assert sum(s["histogram_us"]["compute"]["counts"]) == 2
    assert s["histogram_us"]["lateness"]["counts"] == []
