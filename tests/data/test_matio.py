"""MATLAB files in (rigd.data.matio): v5 and v7.3 read as the same record as the CSV they
were written beside (same fits to 1e-9 through identify); the DaISy records; every refusal
one line naming file, variable and column, exit status 2."""

import json

import numpy as np
import pytest
import scipy.io
from testpaths import SHARED

from rigd.api.data import load
from rigd.cli import main
from tests.gen import linear

DAISY = SHARED / "data" / "daisy"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    d = tmp_path_factory.mktemp("mat")
    g = linear.structure_2in_3modes(seed=11, n=1500)
    return g, g.write_csv(d / "r.csv"), g.write_mat(d / "r5.mat"), \
        g.write_mat(d / "r73.mat", v73=True)


def test_v5_and_v73_load_the_csv_samples(written):
    g, csv, m5, m73 = written
    ref = load(csv, fs=str(g.fs), inputs="force1,force2", outputs="disp1")
    for path in (m5, m73):
        rec = load(path, var="data", inputs="2:3", outputs="4", time_column="1")
        assert rec.fs == pytest.approx(g.fs, rel=1e-12)
        assert rec.meta["inputs"] == ["col2", "col3"] and rec.meta["outputs"] == ["col4"]
        for a, b in (("t", "t"), ("col2", "force1"), ("col3", "force2"), ("col4", "disp1")):
            assert np.array_equal(rec.col(a), ref.col(b))
        # --fs instead of a time column
        assert np.array_equal(load(path, fs="10", inputs="2,3", outputs="4").col("col3"),
                              ref.col("force2"))


def _identify(capsys, path, *opts):
    assert main(["identify", str(path), *opts, "--order", "1", "--method", "oe",
                 "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _fits(js):
    return _numbers(js, ("fit",))


def test_identify_mat_equals_csv(written, capsys):
    g, csv, m5, m73 = written
    ref = _fits(_identify(capsys, csv, "--fs", str(g.fs), "--inputs", "force1,force2",
                          "--outputs", "disp1"))
    assert ref
    for path in (m5, m73):
        got = _fits(_identify(capsys, path, "--var", "data", "--time-column", "1",
                              "--inputs", "2:3", "--outputs", "4"))
        assert np.allclose(got, ref, rtol=0, atol=1e-9)


def test_variables_by_name(tmp_path):
    """An iddata-style export: separate u and y variables (a row vector is a signal too)."""
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((500, 2)), rng.standard_normal((500, 1))
    scipy.io.savemat(tmp_path / "uy.mat", {"u": u, "y": y.T, "note": "text"})
    rec = load(tmp_path / "uy.mat", var="u", inputs="u", outputs="y", fs="2")
    assert rec.meta["inputs"] == ["u_1", "u_2"] and rec.meta["outputs"] == ["y"]
    assert np.array_equal(rec.col("y"), y[:, 0]) and rec.fs == 2.0


@pytest.mark.skipif(not DAISY.is_dir(), reason="../shared/data/daisy not present")
@pytest.mark.parametrize("name, tcol, ins, outs", [
    ("dryer2", "1", "2:4", "5:7"), ("pHdata", "1", "2:3", "4"), ("cstr", None, "2", "3:4"),
    ("steamgen", "1", "2:5", "6:9"), ("glassfurnace", "1", "2:4", "5:10"),
    ("thermic", None, "1:2", "3"), ("winding", None, "1:5", "6:7"),
    ("evaporator", None, "1:3", "4:6")])
def test_daisy_records(name, tcol, ins, outs, tmp_path):
    m = scipy.io.loadmat(DAISY / f"{name}.mat")[name]
    kw = {"time_column": tcol} if tcol else {"fs": "1"}
    rec = load(DAISY / f"{name}.mat", inputs=ins, outputs=outs, **kw)
    assert rec.n == m.shape[0]
    for c in rec.meta["inputs"] + rec.meta["outputs"]:
        assert np.array_equal(rec.col(c), m[:, int(c[3:]) - 1])
    if tcol:
        assert rec.fs == pytest.approx(1.0 / np.median(np.diff(m[:, 0])))
    # the same matrix as a plain CSV reads back the same numbers
    head = [f"c{k + 1}" for k in range(m.shape[1])]
    np.savetxt(tmp_path / "d.csv", m, delimiter=",", header=",".join(head), comments="",
               fmt="%.17g")
    a, b = (int(x) for x in ins.split(":")) if ":" in ins else (int(ins), int(ins))
    csv = load(tmp_path / "d.csv", fs=str(rec.fs), inputs=",".join(head[a - 1:b]),
               outputs=head[-1])
    assert np.array_equal(rec.col(f"col{a}"), csv.col(f"c{a}"))


@pytest.mark.skipif(not DAISY.is_dir(), reason="../shared/data/daisy not present")
def test_identify_daisy_mat_equals_csv(tmp_path, capsys):
    m = scipy.io.loadmat(DAISY / "dryer2.mat")["dryer2"]
    head = ["t", "fuel", "fan", "feed", "dry", "wet", "moist"]
    np.savetxt(tmp_path / "d.csv", m, delimiter=",", header=",".join(head), comments="",
               fmt="%.17g")
    ref = _fits(_identify(capsys, tmp_path / "d.csv", "--fs", "1", "--inputs", "fuel",
                          "--outputs", "dry"))
    got = _fits(_identify(capsys, DAISY / "dryer2.mat", "--time-column", "1", "--inputs", "2",
                          "--outputs", "5"))
    assert ref and np.allclose(got, ref, rtol=0, atol=1e-9)


def _refused(capsys, args):
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


def test_refusals(tmp_path, capsys, written):
    g, csv, m5, m73 = written
    two = tmp_path / "two.mat"
    scipy.io.savemat(two, {"a": np.ones((50, 3)), "b": np.ones((50, 2)),
                           "s": {"x": 1.0}, "wide": np.ones((3, 50))})
    tcol = np.arange(50.0)
    tcol[20] = 19.0
    scipy.io.savemat(tmp_path / "t.mat", {"d": np.column_stack([tcol, np.ones((50, 2))])})
    (tmp_path / "fake.mat").write_text("a,b\n1,2\n")
    cases = [
        (["identify", str(two), "--inputs", "1", "--outputs", "2", "--fs", "1"],
         ["two.mat", "--var", "a, b, wide"]),
        (["identify", str(two), "--var", "zz", "--inputs", "1", "--outputs", "2", "--fs", "1"],
         ["'zz'", "the file has"]),
        (["identify", str(two), "--var", "s", "--inputs", "1", "--outputs", "2", "--fs", "1"],
         ["'s'", "not a numeric matrix"]),
        (["identify", str(two), "--var", "wide", "--inputs", "1", "--outputs", "2",
          "--fs", "1"], ["'wide'", "3x50", "one sample a row"]),
        (["compare", "--help"], None),
    ]
    for args, words in cases:
        if words is None:
            continue
        err = _refused(capsys, args)
        for w in words:
            assert w in err, (w, err)
    for cmd_tail, words in [
        (["--inputs", "2:9", "--outputs", "4", "--time-column", "1"],
         ["r5.mat", "variable 'data'", "--inputs", "column 9", "4 columns"]),
        (["--inputs", "3:2", "--outputs", "4", "--fs", "10"], ["bad column range", "'3:2'"]),
        (["--inputs", "2", "--outputs", "4"], ["no sample rate", "--fs", "--time-column"]),
        (["--inputs", "2", "--outputs", "volts", "--fs", "10"], ["'volts'", "--outputs"]),
        (["--inputs", "2", "--outputs", "2", "--fs", "10"], ["col2", "input and as output"]),
        (["--inputs", "2", "--outputs", "4", "--time-column", "1", "--fs", "3"],
         ["disagrees", "col1"]),
    ]:
        for cmd in ("identify", "diagnose"):
            err = _refused(capsys, [cmd, str(m5), "--var", "data", *cmd_tail])
            for w in words:
                assert w in err, (cmd, w, err)
    err = _refused(capsys, ["identify", str(tmp_path / "t.mat"), "--inputs", "2",
                            "--outputs", "3", "--time-column", "1"])
    assert "t.mat" in err and "variable 'd'" in err and "not increasing" in err
    err = _refused(capsys, ["identify", str(csv), "--var", "x", "--fs", "1", "--inputs",
                            "force1", "--outputs", "disp1"])
    assert "--var" in err and ".mat" in err
    err = _refused(capsys, ["identify", str(tmp_path / "fake.mat"), "--fs", "1", "--inputs",
                            "a", "--outputs", "b"])
    assert "fake.mat" in err and "MAT-file header" in err
    err = _refused(capsys, ["export", str(csv), "--var", "data", "-o", str(tmp_path / "o.csv")])
    assert "--var" in err


def test_export_mat_to_csv(written, tmp_path, capsys):
    g, csv, m5, m73 = written
    out = tmp_path / "o.csv"
    assert main(["export", str(m73), "--var", "data", "--time-column", "1", "--inputs", "2:3",
                 "--outputs", "4", "-o", str(out)]) == 0
    capsys.readouterr()
    rec = load(out)
    assert rec.meta["inputs"] == ["col2", "col3"]
    assert np.array_equal(rec.col("col4"), g.y[:, 0])


def _cli_json(capsys, args):
    assert main([*args, "--json"]) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def _numbers(js, keys=("fit", "score")):
    """Every number under a key naming a fit or a score, walked in a fixed order."""
    out = []

    def walk(v):
        if isinstance(v, dict):
            for k in sorted(v):
                if any(w in k for w in keys) and isinstance(v[k], (int, float)):
                    out.append(float(v[k]))
                walk(v[k])
        elif isinstance(v, list):
            for x in v:
                walk(x)
    walk(js)
    return out


def test_compare_and_diagnose_mat_equal_csv(written, tmp_path, capsys):
    """compare --part validation and diagnose read the v5 and v7.3 files as the CSV: every
    fit and score the same to 1e-9 (each source's own model file: the channel names differ)."""
    g, csv, m5, m73 = written
    fit = ["--order", "1", "--method", "oe"]
    sources = {"csv": [str(csv), "--fs", str(g.fs), "--inputs", "force1,force2", "--outputs",
                       "disp1"]}
    for tag, path in (("v5", m5), ("v73", m73)):
        sources[tag] = [str(path), "--var", "data", "--time-column", "1", "--inputs", "2:3",
                        "--outputs", "4"]
    got = {}
    for tag, src in sources.items():
        mpath = tmp_path / f"{tag}.yaml"
        assert main(["identify", *src, *fit, "-o", str(mpath)]) == 0
        capsys.readouterr()
        cmp = _cli_json(capsys, ["compare", str(mpath), *src, "--part", "validation"])
        assert cmp["initial_state"] == {"generic": "estimation"}
        dia = _cli_json(capsys, ["diagnose", *src, *fit, "--effects",
                                 "static_nonlinearity,delay"])
        got[tag] = (_numbers(cmp), _numbers({k: dia[k] for k in ("fit_percent", "findings",
                                                                  "steps")}))
    ref = got.pop("csv")
    assert ref[0] and ref[1]
    for tag, (c, d) in got.items():
        assert np.allclose(c, ref[0], rtol=0, atol=1e-9), tag
        assert len(d) == len(ref[1]) and np.allclose(d, ref[1], rtol=0, atol=1e-9), tag


def test_non_numeric_and_non_finite_refused_as_in_csv(tmp_path, capsys):
    """A text matrix, a cell array and a NaN in a used column: one line naming the file (and
    the variable, or the column and sample of the NaN), exit 2, as the CSV's bad cells."""
    rng = np.random.default_rng(3)
    d = np.column_stack([np.arange(600) / 10.0, rng.standard_normal((600, 2))])
    bad = d.copy()
    bad[250, 2] = np.nan
    scipy.io.savemat(tmp_path / "x.mat", {"txt": np.array(["abc", "def"]), "d": d,
                                          "c": np.array([[1.0, "a"]], dtype=object),
                                          "bad": bad})
    for var in ("txt", "c"):
        err = _refused(capsys, ["identify", str(tmp_path / "x.mat"), "--var", var,
                                "--inputs", "1", "--outputs", "2", "--fs", "1"])
        assert "x.mat" in err and f"'{var}'" in err and "not a numeric matrix" in err
    np.savetxt(tmp_path / "bad.csv", bad, delimiter=",", header="t,u,y", comments="",
               fmt="%.17g")
    csv_err = _refused(capsys, ["identify", str(tmp_path / "bad.csv"), "--fs", "10",
                                "--inputs", "u", "--outputs", "y"])
    err = _refused(capsys, ["identify", str(tmp_path / "x.mat"), "--var", "bad",
                            "--time-column", "1", "--inputs", "2", "--outputs", "3"])
    # the same words as the CSV's: what, which column, which sample (0-based), who uses it
    assert "x.mat" in err and "NaN in column 'col3' at sample 250" in err, err
    assert "NaN in column 'y' at sample 250" in csv_err, csv_err
    tail = err.split("x.mat: ", 1)[1].replace("'col3'", "'y'")
    assert csv_err.endswith(tail), (err, csv_err)
