"""A rigd recording with invalid samples (NaN while a driver was disconnected or its data were
stale, docs/data.md "Invalid samples"): export, identify, compare and diagnose refuse it in one
line naming the first invalid stretch and the longest valid one, which ``--range`` then takes."""

import numpy as np
import pytest

from rigd.cli import main
from rigd.data.csvio import read_csv
from rigd.data.h5io import write_h5
from rigd.data.record import Record

FS = 1000.0
N = 6000
BAD = slice(2000, 2600)


@pytest.fixture()
def rec(tmp_path):
    rng = np.random.default_rng(0)
    u = rng.standard_normal(N)
    y = np.convolve(u, [0.0, 0.5, 0.25], mode="full")[:N] + 0.01 * rng.standard_normal(N)
    y[BAD] = np.nan                                   # the outage, recorded as invalid
    r = Record({"t": np.arange(N) / FS, "u1": u, "y1": y}, FS,
               {"inputs": ["u1"], "outputs": ["y1"], "rigd_version": "test", "kind": "free"},
               str(tmp_path / "r.h5"))
    path = tmp_path / "r.h5"
    write_h5(path, r)
    return path


@pytest.mark.parametrize("cmd", [["identify", "-o", "m.yaml"], ["diagnose"]])
def test_modelling_refuses_an_invalid_stretch_naming_it(rec, tmp_path, capsys, cmd,
                                                        monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([cmd[0], str(rec), *cmd[1:]]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "600 invalid samples" in err and "samples 2000:2600" in err, err
    assert "--range 2600:6000" in err, err           # the longest valid stretch, to choose


def test_export_refuses_then_exports_the_valid_stretch(rec, tmp_path, capsys):
    out = tmp_path / "out.csv"
    assert main(["export", str(rec), "--csv", str(out)]) == 2
    err = capsys.readouterr().err
    assert "samples 2000:2600" in err and "--range 2600:6000" in err, err
    assert not out.exists()                           # nothing half-written
    assert main(["export", str(rec), "--csv", str(out), "--range", "2600:6000"]) == 0
    back = read_csv(out)
    assert back.n == 3400 and np.all(np.isfinite(back.col("y1")))


def test_a_csv_from_elsewhere_keeps_its_strict_refusal(tmp_path, capsys):
    """The interchange CSV's contract is unchanged: a NaN cell is refused naming its line."""
    p = tmp_path / "other.csv"
    rows = [f"{i / 1000},{(-1) ** (i // 7)},{'NaN' if i == 500 else i % 5}" for i in range(1000)]
    p.write_text("# fs: 1000\n# inputs: [u1]\n# outputs: [y1]\nt,u1,y1\n" + "\n".join(rows)
                 + "\n")
    assert main(["identify", str(p)]) == 2
    err = capsys.readouterr().err
    assert "other.csv:505" in err and "invalid samples" not in err, err
