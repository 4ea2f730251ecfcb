"""One pipeline (rigd.ident.pipeline): diagnose's base model is identify's, with the same
settings — the same numbers, the same start values (``--init``), the same window."""

import benchmarks as B  # tests/diagnose/benchmarks.py
import numpy as np
import pytest

from rigd import api
from rigd.errors import InputError
from rigd.ident.pipeline import FitSettings, analysis_window, method_for


@pytest.fixture(scope="module")
def rec():
    return B.duffing(seed=1, n=2400)


def _ident(rec, **kw):
    sub = api.identify(rec, "generic", **kw).model     # the defaults of both commands
    return sub.submodels["generic"], sub.split["base"]


@pytest.fixture(scope="module")
def default_model(rec):
    """``identify`` with the defaults on ``rec``, fitted once (three tests read it)."""
    return api.identify(rec, "generic").model


def _default(model):
    return model.submodels["generic"], model.split["base"]


def _diag(rec, **kw):
    d = api.diagnose(rec, effects="delay", **kw).diagnosis
    return d.parts[0], d.to_json()["base"]["generic"]


def test_diagnose_base_is_identify_model(rec, default_model):
    sm, base_i = _default(default_model)
    part, base_d = _diag(rec)
    assert list(sm.structure.names) == list(part.steps[0].structure.names)
    np.testing.assert_allclose(part.steps[0].theta, sm.theta, rtol=1e-9, atol=1e-12)
    assert abs(part.fit_percent - sm.fit_percent["validation_mean"]) < 1e-9
    assert base_i == base_d  # method, window, split, hold, order, start, iterations


def test_identify_default_method_is_the_papers_on_the_rotor_and_diagnoses_on_a_generic_record():
    assert method_for("auto", "generic") == "oe"      # rigd diagnose's default
    assert method_for("auto", "actuator") == method_for("auto", "bearing") == "pem"
    assert method_for("pem", "generic") == "pem" and method_for("oe", "bearing") == "oe"
    with pytest.raises(InputError, match="unknown fit method 'ls'") as exc:
        method_for("ls", "generic")
    assert exc.value.where == "--method"


def test_identify_pem_on_a_generic_record_is_another_model(rec, default_model):
    """The default matters: the same record by PEM is a different fit (so the equality above
    is the defaults', not a coincidence)."""
    sm, _ = _default(default_model)
    sm_pem, base_pem = _ident(rec, method="pem")
    assert base_pem["method"] == "pem" and sm.method == "oe"
    assert not np.allclose(sm_pem.theta, sm.theta, rtol=1e-6)


def test_init_is_honoured_by_both(rec, default_model, tmp_path):
    sm, base_i = _default(default_model)
    default_model.save(tmp_path / "m.yaml")              # what ``out=`` writes
    assert base_i["start"] == "automatic"
    sm2, base_i2 = _ident(rec, init=tmp_path / "m.yaml")
    part2, base_d2 = _diag(rec, init=tmp_path / "m.yaml")
    assert base_i2["start"] == base_d2["start"] == "model file"
    # from the converged model the fit stops at once, in both commands
    assert base_i2["nfev"] == base_d2["nfev"] < base_i["nfev"]
    np.testing.assert_allclose(part2.steps[0].theta, sm2.theta, rtol=1e-9, atol=1e-12)


def test_one_window_rule_for_long_records():
    s = FitSettings()
    assert analysis_window(50_000, s) == (5_000, 45_000)
    assert analysis_window(30_000, s) == (0, 30_000)
    assert analysis_window(50_000, FitSettings(est=slice(0, 100), val=slice(100, 200))) \
        == (0, 50_000)
