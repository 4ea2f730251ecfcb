"""Must show (issue 20): a Bouc–Wen oscillator generated outside rigd (tests/gen/nonlinear.py:
a 1 kg, 16 Hz oscillator with a hysteretic restoring force, RK4 on a 20× finer grid, 500 Hz,
multisine 2–60 Hz — other parameters, rate and excitation than the benchmark's of
test_benchmark_records.py) is named ``hysteresis`` at the restoring force (not
``cubic_stiffness``) by the default catalogue, with the held-out error ÷ ≥ 3."""

import pytest

from rigd.diagnose.diagnosis import diagnose_record
from tests.gen import nonlinear


@pytest.mark.timeout(1800)  # one default diagnosis (restoring-force RK4 refits), busy host
def test_generated_bouc_wen_named_hysteresis_not_cubic_stiffness():
    g = nonlinear.bouc_wen(n=6000, seed=3)
    out = diagnose_record(g.record()).to_json()
    named = [f for f in out["findings"] if f["significant"]]
    assert named and (named[0]["effect"], named[0].get("site")) == (
        "hysteresis", "restoring force"), out["findings"][:3]
    assert "cubic_stiffness" not in [f["effect"] for f in named]
    final = out["steps"][-1]["fit_percent"]
    assert 100 - out["fit_percent"] >= 3 * (100 - final), out["steps"]
