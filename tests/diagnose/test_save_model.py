"""``rigd diagnose --save-model``: the model the diagnosis measured is the model file it
writes — its effects, its fit on the same samples through ``rigd compare``, and a start for
``rigd identify --init`` that the fit does not move away from.

The record: a Duffing oscillator generated from its equation (tests/diagnose/benchmarks.py),
of another seed, length and strength than the diagnosis tests use."""

import json

import benchmarks as B  # tests/diagnose/benchmarks.py
import pytest

from rigd.cli import main
from rigd.data.csvio import write_csv
from rigd.effects import resolve
from rigd.ident.modelfile import load_model

#: two candidates, so that the saved model is the selection's choice, not the only one tried
DIAG = ["--effects", "cubic_stiffness,hysteresis", "--steps", "2"]


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("save-model")
    data = tmp / "duffing.csv"
    write_csv(data, B.duffing(seed=7, n=2400, strength=0.3))
    model = tmp / "m.yaml"
    return data, model, tmp


def test_the_saved_model_is_the_one_the_diagnosis_ended_with(saved, capsys):
    data, model, _ = saved
    assert main(["diagnose", str(data), *DIAG, "--json", "--save-model", str(model)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["saved_model"] == str(model)
    added = [s["added"] for s in out["steps"][1:]]
    assert "cubic_stiffness" in added, out["steps"]
    final_fit = out["steps"][-1]["fit_percent"]
    assert final_fit > out["steps"][0]["fit_percent"] + 1.0

    mf = load_model(model, resolve)
    sm = mf.submodels["generic"]
    assert list(sm.structure.effects) == added
    # the model file's own validation figure is the diagnosis's last step
    assert sm.fit_percent["validation_mean"] == pytest.approx(final_fit, abs=0.01)
    assert all(s >= 0 for s in sm.std)          # every parameter has its uncertainty

    # rigd compare on the same record and samples reproduces the diagnosis's figure
    assert main(["compare", str(model), str(data), "--part", "validation", "--json"]) == 0
    cmp_ = json.loads(capsys.readouterr().out)
    assert cmp_["fit_percent"] == pytest.approx(final_fit, abs=0.01)


def test_the_saved_model_starts_identify_where_the_diagnosis_left_it(saved, capsys):
    data, model, tmp = saved
    if not model.exists():
        assert main(["diagnose", str(data), *DIAG, "--json", "--save-model", str(model)]) == 0
        capsys.readouterr()
    added = list(load_model(model, resolve).submodels["generic"].structure.effects)
    again = tmp / "again.yaml"
    assert main(["identify", str(data), "--init", str(model), "--add", ",".join(added),
                 "--method", "oe", "-o", str(again), "--json"]) == 0
    ident = json.loads(capsys.readouterr().out)
    before = load_model(model, resolve).submodels["generic"].fit_percent["validation_mean"]
    # from the diagnosis's parameters the refit keeps (at least) the diagnosis's fit
    assert ident["fit_percent"] >= before - 0.5, (ident["fit_percent"], before)


def test_a_bad_record_is_one_line_and_writes_no_model_file(tmp_path, capsys):
    p = tmp_path / "x.csv"
    p.write_text("a,b\n1,2\n")
    rc = main(["diagnose", str(p), "--save-model", str(tmp_path / "m.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert not (tmp_path / "m.yaml").exists()
