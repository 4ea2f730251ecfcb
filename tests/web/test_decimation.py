"""Server-side min/max decimation of records: block-wise (HDF5, bounded memory) equals the
whole-array decimation, for any block size, windows and NaN; an HDF5 recording and its CSV
export give the same view."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rigd.data.csvio import write_csv
from rigd.data.h5io import write_h5
from rigd.data.record import Record
from rigd.web.runs import minmax, minmax_blocks, record_view


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 3000), buckets=st.integers(1, 400), block=st.integers(1, 700),
       start_frac=st.floats(0, 0.9), nan_at=st.integers(-1, 2999), seed=st.integers(0, 99))
def test_blocks_equal_whole_array(n, buckets, block, start_frac, nan_at, seed):
    x = np.random.default_rng(seed).normal(size=(n, 2))
    if 0 <= nan_at < n:
        x[nan_at, 1] = np.nan
    start = int(start_frac * n)
    stop = n
    blocks = [(s, x[s:s + block]) for s in range(0, n, block)]
    idx, lo, hi = minmax_blocks(blocks, start, stop, buckets, 2)
    for k in range(2):
        i2, lo2, hi2 = minmax(x[start:stop, k], buckets)
        assert np.array_equal(idx, i2 + start)
        # a bucket with a NaN: fmin/fmax skip it (the finite extremes are shown)
        finite = ~np.isnan(lo2)
        assert np.array_equal(lo[finite, k], lo2[finite])
        assert np.array_equal(hi[finite, k], hi2[finite])


@pytest.mark.parametrize("fmt", ["h5", "csv"])
def test_record_view_hdf5_and_csv_agree(tmp_path, fmt):
    n = 30_011
    t = np.arange(n) / 5000.0
    e_x = np.sin(2 * np.pi * 7 * t)
    e_x[12_345] = 5.0
    cols = {"t": t, "r_x": np.zeros(n), "r_y": np.zeros(n), "u_x": np.zeros(n),
            "u_y": np.zeros(n), "e_x": e_x, "e_y": -e_x}
    rec = Record(cols, 5000.0, {"omega_rpm": 0.0, "p_inj_bar": 4.0, "kind": "prbs"})
    p = tmp_path / f"r.{fmt}"
    (write_h5 if fmt == "h5" else write_csv)(p, rec)
    v = record_view(p, points=500, channels=["e_x", "e_y"])
    assert v["n"] == n and len(v["t_s"]) == 500 and v["decimated"]
    i, lo, hi = minmax(e_x, 500)
    assert v["channels"]["e_x"]["max"] == pytest.approx(list(hi))
    assert v["channels"]["e_y"]["min"] == pytest.approx(list(-hi))
    assert max(v["channels"]["e_x"]["max"]) == 5.0
    w = record_view(p, points=500, t0=2.0, t1=2.5)
    assert w["start"] == 10_000 and w["stop"] == 12_501 and "t" not in w["channels"]
    assert set(w["channels"]) == {"r_x", "r_y", "u_x", "u_y", "e_x", "e_y"}
