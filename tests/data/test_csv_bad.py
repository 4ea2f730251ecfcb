"""The strict interchange-CSV reader refuses every kind of bad file with one located message."""

import subprocess
import sys

import numpy as np
import pytest

from rigd.data import load_record
from rigd.errors import InputError

RIGD = "import sys; from rigd.cli import main; sys.exit(main())"
HEAD = "# rig-data: 1\n# fs: 5000\n# omega_rpm: 0\n# p_inj_bar: 4.0\n"
GOOD = HEAD + "t,r_x,e_x\n0.0,1.0,0.5\n0.0002,1.0,0.6\n0.0004,-1.0,0.7\n"

# name -> (file text, line named in the message (None: no line), words the message must hold)
BAD = {
    "empty": ("", None, "empty file"),
    "blank_lines_only": ("\n\n  \n", None, "empty file"),
    "metadata_only": (HEAD, None, "no header row"),
    "header_only": (HEAD + "t,r_x\n", 5, "header only"),
    "missing_fs": ("# omega_rpm: 0\n# p_inj_bar: 4\nt,e_x\n0,1\n", None, "missing required "
                   "metadata 'fs'"),
    "no_metadata": ("t,e_x\n0,1\n", None, "no metadata lines"),
    "fs_negative": ("# fs: -5\n# omega_rpm: 0\n# p_inj_bar: 4\nt,e_x\n0,1\n", 1,
                    "positive finite"),
    "fs_text": ("# fs: fast\n# omega_rpm: 0\n# p_inj_bar: 4\nt,e_x\n0,1\n", 1,
                "fs must be a number"),
    "fs_zero": ("# fs: 0\n# omega_rpm: 0\n# p_inj_bar: 4\nt,e_x\n0,1\n", 1, "positive"),
    "bad_yaml": ("# fs: [5000\n# omega_rpm: 0\n# p_inj_bar: 4\nt,e_x\n0,1\n", 1,
                 "bad metadata YAML"),
    "meta_twice": (HEAD + "# fs: 4000\nt,e_x\n0,1\n", 5, "given twice"),
    "missing_p_inj": ("# fs: 5000\n# omega_rpm: 0\nt,e_x\n0,1\n", None, "p_inj_bar"),
    "missing_omega": ("# fs: 5000\n# p_inj_bar: 4\nt,e_x\n0,1\n", None, "omega_rpm"),
    "missing_t": (HEAD + "r_x,e_x\n1,2\n", 5, "missing required column 't'"),
    "missing_phi": ("# fs: 5000\n# omega_rpm: 3000\n# p_inj_bar: 4\nt,e_x\n0,1\n", 4,
                    "missing required column 'phi'"),
    "duplicate_column": (HEAD + "t,e_x,e_x\n0,1,2\n", 5, "duplicate column 'e_x'"),
    "empty_column_name": (HEAD + "t,e_x,\n0,1,2\n", 5, "empty column name"),
    "t_non_numeric": (HEAD + "t,e_x\n0,1\n0.0002x,1\n", 7, "non-numeric cell '0.0002x' in "
                      "column 't'"),
    "t_empty": (HEAD + "t,e_x\n0,1\n,1\n", 7, "empty cell in column 't'"),
    "t_nan": (HEAD + "t,e_x\n0,1\nnan,1\n", 7, "nan in column 't'"),
    "ragged_short": (HEAD + "t,e_x,e_y\n0,1,2\n0.0002,1\n", 7, "ragged row: 2 cells, header "
                     "has 3"),
    "ragged_long": (HEAD + "t,e_x\n0,1\n0.0002,1,5\n", 7, "ragged row: 3 cells"),
    "t_not_monotonic": (HEAD + "t,e_x\n0,1\n0.0002,1\n0.0001,1\n", 8, "t not increasing"),
    "t_repeated": (HEAD + "t,e_x\n0,1\n0,1\n", 7, "t not increasing"),
    "t_vs_fs": (HEAD + "t,e_x\n0,1\n0.001,1\n0.002,1\n", 7, "inconsistent with fs"),
    "inputs_missing_column": ("# fs: 100\n# inputs: [u]\n# outputs: [y]\nV1,y\n1,2\n", 4,
                              "'u' declared in inputs"),
    "inputs_without_outputs": ("# fs: 100\n# inputs: [V1]\nV1,V2\n1,2\n", 2,
                               "inputs declared without outputs"),
    "comment_in_data": (HEAD + "t,e_x\n0,1\n# late: 1\n0.0002,1\n", 7, "'#' line after the "
                        "header"),
    "version": ("# rig-data: 2\n# fs: 5000\n# omega_rpm: 0\n# p_inj_bar: 4\nt\n0\n", 1,
                "unsupported rig-data version"),
    "quoted_header": ('"V1","V2",\n1,2,\n', 1, "rigd export --from-csv"),
    "binary": (None, None, "not a text file"),
}


def _write(tmp_path, name, text):
    p = tmp_path / f"{name}.csv"
    if text is None:
        p.write_bytes(b"\x00\xff\xfe\x81\x90" * 50)
    else:
        p.write_text(text)
    return p


def test_good_file_reads(tmp_path):
    rec = load_record(_write(tmp_path, "good", GOOD))
    assert rec.fs == 5000.0 and rec.n == 3
    assert rec.omega_rpm == 0.0 and rec.p_inj_bar == 4.0
    np.testing.assert_array_equal(rec.col("e_x"), [0.5, 0.6, 0.7])


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_file_refused(tmp_path, name):
    text, line, words = BAD[name]
    p = _write(tmp_path, name, text)
    with pytest.raises(InputError) as info:
        load_record(p)
    msg = str(info.value)
    assert "\n" not in msg
    assert words in msg, msg
    expected_where = f"{p}:{line}:" if line else f"{p}:"
    assert msg.startswith(expected_where), msg


# a bad cell outside `t` is refused when its column is used (Record.check_finite):
# name -> (file text, line named, words)
BAD_CELLS = {
    "non_numeric": (HEAD + "t,e_x\n0,1\n0.0002,abc\n", 7, "non-numeric cell 'abc' in column "
                    "'e_x' at sample 1"),
    "empty_cell": (HEAD + "t,e_x\n0,1\n0.0002,\n", 7, "empty cell in column 'e_x' at sample 1"),
    "nan": (HEAD + "t,e_x\n0,1\n0.0002,nan\n", 7, "NaN in column 'e_x' at sample 1"),
    "inf": (HEAD + "t,e_x\n0,inf\n", 6, "inf in column 'e_x' at sample 0"),
}


@pytest.mark.parametrize("name", sorted(BAD_CELLS))
def test_bad_cell_refused_when_its_column_is_used(tmp_path, name):
    text, line, words = BAD_CELLS[name]
    p = _write(tmp_path, name, text)
    rec = load_record(p)  # the reader keeps it (the column may be unused) ...
    rec.check_finite(["t"])
    with pytest.raises(InputError) as info:  # ... a command using e_x refuses it
        rec.check_finite(["t", "e_x"], "the bearing model")
    msg = str(info.value)
    assert "\n" not in msg and words in msg and "used by the bearing model" in msg, msg
    assert msg.startswith(f"{p}:{line}:"), msg


def test_spec_example_with_comments_and_unknown_keys(tmp_path):
    text = ("# rig-data: 1\n# fs: 5000            # sample rate, Hz (required)\n"
            "# omega_rpm: 1200    # shaft speed\n# p_inj_bar: 4.0\n# kind: prbs          # k\n"
            "# note: any text\n# operator: J. Doe: night shift\n# a free-form line\n\n"
            "t,r_x,r_y,u_x,u_y,e_x,e_y,phi,extra\n"
            "0.0000,1.0,-1.0,0.013,-0.002,0.41,-0.27,0.000,7\n\n"
            "0.0002,1.0,-1.0,0.013,-0.002,0.41,-0.27,0.100,7\n")
    rec = load_record(_write(tmp_path, "spec", text))
    assert rec.kind == "prbs" and rec.omega_rpm == 1200.0
    assert rec.meta["note"] == "any text"
    assert rec.meta["operator"] == "J. Doe: night shift"
    assert rec.meta["comments"] == ["a free-form line"]
    assert rec.n == 2 and "extra" in rec.columns


def test_generic_record(tmp_path):
    text = "# rig-data: 1\n# fs: 610.35\n# inputs: [V1]\n# outputs: [V2]\nV1,V2\n1,2\n3,4\n"
    rec = load_record(_write(tmp_path, "gen", text))
    assert rec.is_generic and rec.inputs == ["V1"] and rec.outputs == ["V2"]


def test_large_file_in_several_blocks_locates_late_error(tmp_path):
    n = 140_000  # more than two parse blocks
    t = np.arange(n) / 5000.0
    body = "".join(f"{ti!r},{i}\n" for i, ti in enumerate(t.tolist()))
    p = tmp_path / "big.csv"
    p.write_text(HEAD + "t,e_x\n" + body)
    rec = load_record(p)
    assert rec.n == n and np.array_equal(rec.col("t"), t)
    lines = p.read_text().splitlines(keepends=True)
    lines[5 + 135_000] = "27.0,oops\n"
    p.write_text("".join(lines))
    rec = load_record(p)
    with pytest.raises(InputError, match=rf":{5 + 135_000 + 1}: non-numeric cell 'oops' in "
                                         "column 'e_x' at sample 135000"):
        rec.check_finite(["e_x"])
    with pytest.raises(InputError, match=rf":{5 + 135_001}: non-numeric cell 'oops'"):
        rec.slice(135_000).check_finite(["e_x"])  # a range keeps the file's line


def test_silverbox_raw_refused_then_loaded_with_fs(tmp_path):
    """The Silverbox raw CSV as the repository ships it (examples/data, gzip: read as the
    plain file) — a clone needs nothing beside it."""
    from testpaths import ROOT

    raw = ROOT / "examples" / "data" / "silverbox.csv.gz"
    with pytest.raises(InputError, match="rigd export --from-csv"):
        load_record(raw)
    rec = load_record(raw, fs=1e7 / 2 ** 14, inputs="V1", outputs=["V2"])
    assert rec.n == 131072 and rec.inputs == ["V1"] and rec.outputs == ["V2"]
    assert rec.fs == pytest.approx(610.3515625)
    assert rec.col("V1")[0] == 0.0057756 and rec.col("V2")[-1] == -0.0072247


def test_raw_csv_bad_cases(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text('"a","b",\n1,2,\n3,\n')
    with pytest.raises(InputError, match=r"r.csv:3: ragged row"):
        load_record(p, fs=10, inputs="a", outputs="b")
    p.write_text('"a","b",\n1,2,\n')
    with pytest.raises(InputError, match=r"'c' declared in outputs"):
        load_record(p, fs=10, inputs="a", outputs="c")
    with pytest.raises(InputError, match="missing required metadata 'omega_rpm'"):
        load_record(p, fs=10)


@pytest.mark.parametrize("name", ["non_numeric", "missing_fs", "ragged_short"])
def test_cli_refuses_bad_file_one_line_no_output(tmp_path, name):
    text, line, words = {**BAD, **BAD_CELLS}[name]  # export uses every column
    src = _write(tmp_path, name, text)
    out = tmp_path / "out.csv"
    proc = subprocess.run([sys.executable, "-c", RIGD, "export", str(src), "--csv",
                           str(out)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and words in err[0] and str(src) in err[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == [src]
