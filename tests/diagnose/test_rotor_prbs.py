"""Rotor records under a binary PRBS (the paper's excitation) from the project's simulated
plant, valve effects switched on."""


from rigd.diagnose.diagnosis import diagnose_record
from rigd.experiments.signals import prbs
from rigd.loop import sim

FS = 5000.0


def test_hysteresis_under_binary_prbs_cannot_tell_and_asks_for_multilevel():
    """With a two-level input the valves' hysteresis acts as a gain change: nothing can be
    found (right), and the diagnosis says it cannot tell and which experiment would."""
    exc = prbs(FS, 2.0, 1.0, min_hold_s=0.001, switch_probability=0.5, seed=1)
    rec = sim.simulate_record(excitation=exc, seed=1, effects=["hysteresis"])
    out = diagnose_record(rec, submodels=["actuator"]).to_json()
    assert [f["effect"] for f in out["findings"] if f["significant"]] == []
    why = [c for c in out["cannot_reveal"] if c["effect"] == "hysteresis"]
    assert why and "2 levels" in why[0]["why"] and "multi-level" in why[0]["experiment"]
