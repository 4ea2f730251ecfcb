"""HDF5 recordings read by channel name; export to CSV reads back bit-for-bit; crash-truncated
SWMR files read up to the last flush."""

import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest

from rigd.data import Record, load_record
from rigd.data.export import export_csv
from rigd.data.h5io import write_h5
from rigd.errors import InputError
from rigd.frame import RECORD_CHANNELS, RECORD_NAMES

RIGD = "import sys; from rigd.cli import main; sys.exit(main())"


def _record(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    cols = {k: rng.standard_normal(n) * 10.0 ** rng.uniform(-8, 8) for k in RECORD_NAMES}
    cols["seq"] = np.arange(n) + 100.0
    cols["t"] = cols["seq"] / 5000.0
    cols["phi"] = np.mod(cols["t"] * 2 * np.pi * 20, 2 * np.pi)
    cols["e_x"][:3] = [0.1, 1e-300, -2.5e-17]          # awkward floats
    meta = {"omega_rpm": 1200.0, "p_inj_bar": 4.0, "kind": "prbs", "config": "a: 1\nb: [2]\n",
            "created": "2024-05-01T10:00:00+00:00", "experiment": "prbs-test",
            "units": dict(RECORD_CHANNELS)}
    return Record(cols, 5000.0, meta, "mem")


def test_h5_reads_channels_and_attrs(tmp_path):
    rec = _record()
    p = tmp_path / "r.h5"
    write_h5(p, rec)
    got = load_record(p)
    assert list(got.columns) == list(RECORD_NAMES)
    for k in RECORD_NAMES:
        assert np.array_equal(got.columns[k], rec.columns[k])
    assert got.fs == 5000.0 and got.omega_rpm == 1200.0 and got.p_inj_bar == 4.0
    assert got.kind == "prbs" and got.meta["experiment"] == "prbs-test"
    assert got.meta["units"]["e_x"] == "um"


def test_export_roundtrip_bit_for_bit_cli(tmp_path):
    rec = _record(n=40_000)
    p = tmp_path / "r.h5"
    write_h5(p, rec)
    out = tmp_path / "r.csv"
    proc = subprocess.run([sys.executable, "-c", RIGD, "export", str(p), "--csv", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    back = load_record(out)
    assert list(back.columns)[0] == "t"
    for k in RECORD_NAMES:
        assert back.columns[k].tobytes() == rec.columns[k].tobytes(), k
    assert back.fs == rec.fs and back.meta["config"] == rec.meta["config"]
    assert back.meta["created"] == rec.meta["created"] and back.kind == "prbs"
    # exporting the CSV again gives the identical file
    out2 = tmp_path / "r2.csv"
    export_csv(out, out2)
    assert out2.read_bytes() == out.read_bytes()


def test_export_columns_subset(tmp_path):
    p = tmp_path / "r.h5"
    write_h5(p, _record())
    out = tmp_path / "s.csv"
    export_csv(p, out, columns=["e_x", "e_y", "phi"])
    back = load_record(out)
    assert list(back.columns) == ["t", "e_x", "e_y", "phi"]
    with pytest.raises(InputError, match="no channel"):
        export_csv(p, tmp_path / "x.csv", columns=["nope"])
    assert not (tmp_path / "x.csv").exists()


def test_export_refuses_nan_leaves_no_file(tmp_path):
    rec = _record(n=50_000)
    rec.columns["e_y"][45_000] = np.nan
    p = tmp_path / "r.h5"
    write_h5(p, rec)
    out = tmp_path / "o.csv"
    # an invalid sample (NaN) of a recording: named, with the valid stretch to export
    with pytest.raises(InputError, match=r"column 'e_y', used by the export, in 1 stretch\(es\), "
                                         r"the first at sample 45000 .*--range 0:45000"):
        export_csv(p, out, block_rows=10_000)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["r.h5"]


def test_export_does_not_overwrite_input(tmp_path):
    p = tmp_path / "r.h5"
    write_h5(p, _record())
    with pytest.raises(InputError, match="output is the input"):
        export_csv(p, p)


def test_not_a_recording(tmp_path):
    p = tmp_path / "x.h5"
    with h5py.File(p, "w") as f:
        f["other"] = np.zeros(3)
    with pytest.raises(InputError, match="no /frames dataset"):
        load_record(p)
    q = tmp_path / "fake.h5"
    q.write_text("hello")
    with pytest.raises(InputError, match="not an HDF5 file"):
        load_record(q)


WRITER = textwrap.dedent("""
    import os, sys, h5py, numpy as np
    path = sys.argv[1]
    f = h5py.File(path, "w", libver="latest")
    ds = f.create_dataset("frames", shape=(0, 3), maxshape=(None, 3), chunks=(64, 3), dtype="f8")
    ds.attrs["channels"] = ["seq", "t", "e_x"]
    f.attrs["fs"] = 5000.0; f.attrs["omega_rpm"] = 0.0; f.attrs["p_inj_bar"] = 4.0
    f.attrs["kind"] = "runout"
    f.swmr_mode = True
    for k in range(5):
        n0 = ds.shape[0]
        ds.resize((n0 + 100, 3))
        seq = np.arange(n0, n0 + 100, dtype=float)
        ds[n0:] = np.column_stack([seq, seq / 5000.0, np.sin(seq)])
        ds.flush()
    ds.resize((ds.shape[0] + 100, 3))   # allocated, never written
    ds.flush()
    os._exit(0)                          # crash: no close
""")


def test_crashed_swmr_writer_reads_up_to_last_flush(tmp_path):
    p = tmp_path / "crash.h5"
    subprocess.run([sys.executable, "-c", WRITER, str(p)], check=True, timeout=60)
    rec = load_record(p)
    assert rec.n == 500
    assert np.array_equal(rec.col("seq"), np.arange(500.0))
    assert rec.kind == "runout" and rec.meta["truncated_rows"] == 100
