"""Diagnosis on records generated in the test from published benchmark systems
(tests/diagnose/benchmarks.py; no shipped data, no shipped fits, the method's rules fixed
before these records were made)."""

import benchmarks as B  # tests/diagnose/benchmarks.py
import pytest

from rigd.diagnose.diagnosis import diagnose_record


def significant(d):
    return [f["effect"] for f in d.to_json()["findings"] if f["significant"]]


@pytest.mark.parametrize("seed", [0, 1])
def test_duffing_names_cubic_stiffness_and_error_falls(seed):
    d = diagnose_record(B.duffing(seed=seed))
    out = d.to_json()
    top = out["findings"][0]
    assert top["effect"] == "cubic_stiffness" and top["significant"], out["findings"][:3]
    assert significant(d) == ["cubic_stiffness"]
    assert 100 - out["fit_percent"] >= 3 * (100 - top["fit_percent_with"])


def test_linear_oscillator_control_nothing_significant():
    """The Bouc–Wen benchmark's oscillator with its hysteresis switched off (β = 0)."""
    d = diagnose_record(B.bouc_wen_linear(seed=2))
    assert significant(d) == [], d.to_json()["findings"][:3]
    assert d.parts[0].fit_percent >= 95.0
