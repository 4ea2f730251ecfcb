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


def test_three_mode_structure_order_auto_finds_the_missing_modes():
    """One DOF per output misses two of the chain's three modes; order auto finds them."""
    true = B.three_mode_frequencies()
    d = diagnose_record(B.three_mode(seed=3))
    out = d.to_json()
    order = out["order"]["generic"]
    assert order["modes"] == 3, order
    fits = order["validation_fit_by_modes"]
    assert fits["1"] < 80.0 and out["fit_percent"] >= 95.0, fits
    got = d.parts[0].ctx.resonances_hz
    assert len(got) == 3 and all(abs(g - t) < 0.02 * t for g, t in zip(sorted(got), true)), got
    assert any("misses mode(s)" in n for n in out["notes"])
    # the modes are now in the base model: no catalogue effect is forced onto them
    assert significant(d) == []


def test_three_mode_structure_with_one_mode_names_extra_mode():
    d = diagnose_record(B.three_mode(seed=4), order=1)
    out = d.to_json()
    assert out["order"]["generic"]["modes"] == 1
    top = out["findings"][0]
    assert top["effect"] == "extra_mode" and top["significant"], out["findings"][:3]
    assert top["fit_percent_with"] - out["fit_percent"] >= 10.0
