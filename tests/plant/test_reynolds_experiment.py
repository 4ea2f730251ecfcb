"""``rigd experiment`` impacts on the physics-grade plant: the hammer, the operating point set
through the loop, and ``analyze-impact`` agree with the plant's linearised modes."""

from pathlib import Path

import pytest

from rigd.api.experiment import run_experiment
from rigd.api.impact import analyze_impact
from rigd_drivers.sim_reynolds import ReynoldsPlantDriver

CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim_reynolds.yaml"


def _impact_run(tmp_path, p_inj):
    out = tmp_path / f"imp{p_inj:g}"
    run_experiment({"kind": "impact", "name": f"imp-{p_inj:g}",
                    "operating_point": {"omega_rpm": 0.0, "p_inj_bar": p_inj}, "axis": "x",
                    "controller": [False], "repeats": 1, "pre_s": 0.01, "post_s": 0.15,
                    "spacing_s": 0.05, "peak_n": 20.0, "pulse_s": 0.001},
                   config=str(CONFIG), out=out)
    res = analyze_impact(out)
    (imp,) = [s for s in res["summary"] if s["axis"] == "x"]
    assert imp["p_inj_bar"] == p_inj and imp["controller_on"] is False
    return imp


def test_impacts_at_4_and_7_bar_ring_at_the_linearised_first_mode(tmp_path):
    got = {p: _impact_run(tmp_path, p) for p in (4.0, 7.0)}
    for p, imp in got.items():
        lm = ReynoldsPlantDriver({"p_inj_bar": p}).linear_modes()
        assert imp["f_hz"] == pytest.approx(lm.freq_hz[0], rel=0.03)
        assert imp["zeta"] == pytest.approx(lm.zeta[0], rel=0.2)
    assert got[7.0]["f_hz"] > got[4.0]["f_hz"]
    assert got[7.0]["zeta"] < 0.8 * got[4.0]["zeta"]
