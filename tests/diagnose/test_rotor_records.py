"""Rotor records end to end: `rigd experiment` (lock-step on the simulated plant, run-out on)
-> `rigd diagnose REC.h5 [--runout RUNOUT.h5] --json`, both sub-models examined; and the
same base fits as `rigd identify --method oe` on the same record."""

import json
from pathlib import Path

import pytest

from rigd.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp("rotor")
    sim = (ROOT / "config" / "sim.yaml").read_text()
    assert "    runout:\n      enabled: false" in sim
    (d / "sim.yaml").write_text(sim.replace("    runout:\n      enabled: false",
                                            "    runout:\n      enabled: true", 1))
    (d / "ml.yaml").write_text(
        "kind: multilevel\nname: ml-w3000\noperating_point: {omega_rpm: 3000, p_inj_bar: 4.0}\n"
        "amplitude_v: 1.0\nlevels: 7\nmin_hold_s: 0.001\nswitch_probability: 0.7\nseed: 2\n"
        "duration_s: 2.0\nlead_in_s: 0.4\n")
    (d / "ro.yaml").write_text(
        "kind: runout\nname: ro-w3000\noperating_point: {omega_rpm: 3000, p_inj_bar: 4.0}\n"
        "revolutions: 50\ncontroller: false\n")
    for name in ("ml", "ro"):
        assert main(["experiment", str(d / f"{name}.yaml"), "--config", str(d / "sim.yaml"),
                     "--lockstep", "--out", str(d / name)]) == 0
    rec = next((d / "ml").glob("*.h5"))
    ro = next((d / "ro").glob("*.h5"))
    return rec, ro


def _json(capsys, argv):
    capsys.readouterr()
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_rotor_record_both_submodels_runout_found_or_filtered(records, capsys):
    rec, ro = records
    raw = _json(capsys, ["diagnose", str(rec), "--json"])
    assert set(raw["fit_percent"]) == {"actuator", "bearing"}
    assert set(raw["steps"]) == {"actuator", "bearing"}
    sig = [(f["effect"], f["submodel"]) for f in raw["findings"] if f["significant"]]
    assert sig == [("runout", "bearing")]
    b = raw["steps"]["bearing"]
    assert b[1]["added"] == "runout"
    assert (100 - b[0]["fit_percent"]) >= 3 * (100 - b[1]["fit_percent"])
    # with the run-out record the run-out filter F_r(phi) removes it before the diagnosis
    filt = _json(capsys, ["diagnose", str(rec), "--runout", str(ro), "--json"])
    assert not [f for f in filt["findings"] if f["significant"]]
    assert filt["fit_percent"]["bearing"] > 95 and filt["fit_percent"]["actuator"] > 95


def test_rotor_record_same_base_fit_as_identify(records, capsys):
    rec, ro = records
    ident = _json(capsys, ["identify", str(rec), "--runout", str(ro), "--method", "oe",
                           "--json"])
    diag = _json(capsys, ["diagnose", str(rec), "--runout", str(ro), "--json",
                          "--effects", "delay"])
    for sub in ("actuator", "bearing"):
        assert ident["fit_percent"][sub] == pytest.approx(diag["fit_percent"][sub], abs=1e-3)
