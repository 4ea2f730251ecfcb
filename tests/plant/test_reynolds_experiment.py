"""``rigd experiment`` impacts on the physics-grade plant: the hammer, the operating point set
through the loop, and ``analyze-impact`` agree with the plant's linearised modes."""

from pathlib import Path

import pytest

from rigd.api.experiment import run_experiment
from rigd.api.impact import analyze_impact
from rigd_drivers.reynolds.driver import ReynoldsPlantDriver

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


def test_impacts_at_4_and_7_bar_ring_at_the_linearised_mode_of_the_hammered_axis(tmp_path):
    """x hammers through ``rigd experiment`` and ``analyze-impact``: the linearised mode whose
    disc motion is along x (``of_axis``), within 2 % on frequency and 10 % on ζ."""
    got = {p: _impact_run(tmp_path, p) for p in (4.0, 7.0)}
    for p, imp in got.items():
        lm = ReynoldsPlantDriver({"p_inj_bar": p}).linear_modes()
        j = lm.of_axis("x")
        assert imp["f_hz"] == pytest.approx(lm.freq_hz[j], rel=0.02)
        assert imp["zeta"] == pytest.approx(lm.zeta[j], rel=0.10)
    assert got[7.0]["f_hz"] > got[4.0]["f_hz"]
    assert got[7.0]["zeta"] < 0.8 * got[4.0]["zeta"]


def test_sweep_sets_each_operating_point_on_the_plant(tmp_path):
    """A sweep over (Ω, P_I): each record carries its point in the frame (the plant's own
    omega_rpm / p_inj_bar channels), the encoder turns at Ω, and the shaft answers the PRBS."""
    import numpy as np

    from rigd.data import load_record

    out = tmp_path / "sweep"
    res = run_experiment({"kind": "sweep", "name": "sw",
                          "grid": {"omega_rpm": [0.0, 6000.0], "p_inj_bar": [3.0, 7.0]},
                          "at_each": {"kind": "prbs", "amplitude_v": 0.5, "seed": 2,
                                      "duration_s": 0.2, "lead_in_s": 0.05}},
                         config=str(CONFIG), out=out)
    assert res.status == "complete"
    recs = sorted(out.glob("*.h5"))
    assert len(recs) == 4
    seen = set()
    for path in recs:
        rec = load_record(path)
        c = rec.columns
        om, p = float(np.median(c["omega_rpm"])), float(np.median(c["p_inj_bar"]))
        seen.add((om, p))
        turns = np.unwrap(c["phi"])
        rate_rpm = (turns[-1] - turns[0]) / (len(turns) - 1) * rec.fs * 60 / (2 * np.pi)
        assert rate_rpm == pytest.approx(om, abs=1.0)
        assert np.std(c["e_x"]) > 0.2 and np.all(np.abs(c["e_x"]) < 20.0)
    assert seen == {(0.0, 3.0), (0.0, 7.0), (6000.0, 3.0), (6000.0, 7.0)}
