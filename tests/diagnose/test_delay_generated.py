"""Must show (issue 20): a generated heater (a first-order thermal plant simulated outside
rigd, tests/gen/linear.py) with a 3-sample transport delay — ``rigd diagnose``'s default
catalogue names ``delay``, its size (the refit's) is within 1 sample of the truth, and the
held-out error falls. Two heaters of other rates, time constants and seeds; the delay is
comparable to the time constant (a delay of a tenth of the time constant is absorbed by the
base's own lags within the noise: nothing to name there, see docs/diagnose.md)."""

import pytest

from rigd.diagnose.diagnosis import diagnose_record
from tests.gen import linear

HEATERS = {"tau5s_1Hz": dict(tau_s=5.0, fs=1.0, n=2000, seed=1),
           "tau4s_2Hz": dict(tau_s=4.0, fs=2.0, n=2000, seed=2)}


@pytest.mark.timeout(1200)  # one default diagnosis on a busy host
@pytest.mark.parametrize("name", sorted(HEATERS))
def test_heater_delay_named_with_its_size_and_error_falls(name):
    g = linear.thermal(delay=3.0, **HEATERS[name])
    d = diagnose_record(g.record())
    out = d.to_json()
    named = [f for f in out["findings"] if f["significant"]]
    assert named and named[0]["effect"] == "delay", out["findings"][:3]
    ev = next(f for f in d.parts[0].findings if f.effect == "delay").evidence
    assert abs(ev["delay_samples"] - g.truth["delays"][0]) <= 1.0, ev
    # the words say the refit's size, in samples and in time
    assert f"{ev['delay_samples']:.3g}" in named[0]["explanation"] or "3 samples" in \
        named[0]["explanation"], named[0]["explanation"]
    # held-out error falls: by a third at least and by more than the practical-significance
    # gain (at 35 dB the noise alone leaves ≈ 1.8 % of the output's spread: measured
    # 5.44 → 1.84 and 2.94 → 1.82 when the delay was added to a base without one). A delay
    # the base carries (the general LTI family's, chosen before the order) is measured
    # against the same base refitted without it (rigd.ident.lti.delay_worth): the 1-state
    # base of both heaters 58.47 → 98.18 and 73.18 → 98.18
    if ev.get("code") == "delay.in_base":
        final = out["fit_percent"]
        base = final - ev["fit_points_lost"]
        assert f"{ev['fit_points_lost']:.2f} points worse" in named[0]["explanation"]
    else:
        base, final = out["fit_percent"], out["steps"][-1]["fit_percent"]
    assert 100 - final <= (100 - base) * 2 / 3 and final - base >= 0.5, out["steps"]
