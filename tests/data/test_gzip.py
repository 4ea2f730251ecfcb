"""gzip-compressed CSV and MATLAB files (rigd.data.compressed) read as the plain files: the same
record, and every bad file refused with the same located message; a damaged stream or a
compressed HDF5 recording is one clear refusal, exit status 2 from the CLI."""

import gzip
import subprocess
import sys

import numpy as np
import pytest
from test_csv_bad import BAD, GOOD, RIGD
from testpaths import ROOT

from rigd.data import load_record
from rigd.errors import InputError

EXAMPLES = ROOT / "examples" / "data"


def _gz(path, data: bytes):
    path.write_bytes(gzip.compress(data, mtime=0))
    return path


def _same(a, b):
    assert a.fs == b.fs and a.n == b.n and sorted(a.columns) == sorted(b.columns)
    for name in a.columns:
        np.testing.assert_array_equal(a.col(name), b.col(name))


def test_interchange_csv_gz_is_the_plain_record(tmp_path):
    plain = tmp_path / "r.csv"
    plain.write_text(GOOD)
    _same(load_record(_gz(tmp_path / "r.csv.gz", GOOD.encode())), load_record(plain))
    # the name is not trusted: gzip content under a .csv name reads too
    _same(load_record(_gz(tmp_path / "other.csv", GOOD.encode())), load_record(plain))


@pytest.mark.parametrize("name", sorted(k for k, v in BAD.items() if v[0] is not None))
def test_bad_file_refused_the_same_way_compressed(tmp_path, name):
    text, line, words = BAD[name]
    p = _gz(tmp_path / f"{name}.csv.gz", text.encode())
    with pytest.raises(InputError) as info:
        load_record(p)
    msg = str(info.value)
    assert "\n" not in msg and words in msg, msg
    assert msg.startswith(f"{p}:{line}:" if line else f"{p}:"), msg


def test_shipped_silverbox_is_the_benchmark_file(tmp_path):
    gz = EXAMPLES / "silverbox.csv.gz"
    plain = tmp_path / "SNLS80mV.csv"
    plain.write_bytes(gzip.decompress(gz.read_bytes()))
    rec = load_record(gz, fs=1e7 / 2 ** 14, inputs="V1", outputs=["V2"])
    assert rec.n == 131072 and rec.inputs == ["V1"] and rec.outputs == ["V2"]
    assert rec.col("V1")[0] == 0.0057756 and rec.col("V2")[-1] == -0.0072247
    _same(rec, load_record(plain, fs=1e7 / 2 ** 14, inputs="V1", outputs=["V2"]))


def test_shipped_dryer_mat_gz_is_the_mat_record(tmp_path):
    gz = EXAMPLES / "dryer2.mat.gz"
    plain = tmp_path / "dryer2.mat"
    plain.write_bytes(gzip.decompress(gz.read_bytes()))
    opts = {"var": "dryer2", "time_column": "1", "inputs": "2:4", "outputs": "5:7"}
    rec = load_record(gz, **opts)
    assert rec.n == 867 and rec.inputs == ["col2", "col3", "col4"]
    assert rec.outputs == ["col5", "col6", "col7"]
    _same(rec, load_record(plain, **opts))
    # a compressed MAT-file named without .mat is still found by its content
    renamed = tmp_path / "dryer"
    renamed.write_bytes(gz.read_bytes())
    _same(rec, load_record(renamed, **opts))


@pytest.mark.parametrize("cut", [10, 200])
def test_damaged_gzip_is_one_clear_refusal(tmp_path, cut):
    rows = "".join(f"{k / 5000!r},1.0,{np.sin(k)!r}\n" for k in range(3, 3000))
    whole = gzip.compress((GOOD + rows).encode(), mtime=0)
    assert load_record(_gz(tmp_path / "whole.csv.gz", gzip.decompress(whole))).n == 3000
    p = tmp_path / "cut.csv.gz"
    p.write_bytes(whole[:cut])        # truncated: the stream ends early
    with pytest.raises(InputError, match="damaged gzip file") as info:
        load_record(p)
    assert str(info.value).startswith(f"{p}:")


def test_damaged_mat_gz_refused(tmp_path):
    p = tmp_path / "d.mat.gz"
    p.write_bytes((EXAMPLES / "dryer2.mat.gz").read_bytes()[:5000])
    with pytest.raises(InputError, match="damaged gzip file"):
        load_record(p, var="dryer2", time_column="1", inputs="2:4", outputs="5:7")


def test_compressed_hdf5_refused(tmp_path):
    p = _gz(tmp_path / "rec.h5.gz", b"\x89HDF\r\n\x1a\n" + bytes(100))
    with pytest.raises(InputError, match="gzip-compressed HDF5 recording is not read"):
        load_record(p)


def test_cli_damaged_gzip_exit_2_one_line(tmp_path):
    p = tmp_path / "cut.csv.gz"
    p.write_bytes(gzip.compress(GOOD.encode() * 50, mtime=0)[:40])
    out = tmp_path / "out.csv"
    proc = subprocess.run([sys.executable, "-c", RIGD, "export", str(p), "--csv", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and "damaged gzip file" in err[0] and str(p) in err[0], proc.stderr
    assert not out.exists()
