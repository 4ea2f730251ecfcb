"""identify / compare / diagnose say where the record came from: a line on stdout and a
`source` key in --json (simulated records from rigd's simulator; a CSV from elsewhere says
nothing, and the commands say so); the API gives the same."""

import json

import numpy as np
import pytest

from rigd import api
from rigd.cli import main
from rigd.data.csvio import write_csv
from rigd.data.h5io import write_h5
from rigd.data.record import Record
from rigd.loop.sim import simulate_record

SIM = {"source": "simulated", "drivers": {"fast": "sim", "slow": []}}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("src")
    rng = np.random.default_rng(3)
    exc = np.repeat(rng.choice([-1.0, 1.0], size=(300, 2)), 10, axis=0)
    rec = simulate_record(excitation=exc, seed=4, settle_s=0.05)
    assert rec.meta["source"] == "simulated"
    write_h5(d / "sim.h5", rec)
    meta = {k: v for k, v in rec.meta.items() if k not in ("source", "drivers")}
    write_csv(d / "other.csv", Record(rec.columns, rec.fs, meta, "<other>"))
    return d / "sim.h5", d / "other.csv"


def _run(capsys, argv):
    capsys.readouterr()
    assert main(argv) == 0
    return capsys.readouterr().out


def test_identify_prints_and_reports_source(files, capsys, tmp_path):
    h5, csv = files
    out = _run(capsys, ["identify", str(h5), "--model", "actuator", "-o", str(tmp_path / "m.yaml")])
    assert out.splitlines()[0] == "source: simulated (drivers: fast sim)"
    js = json.loads(_run(capsys, ["identify", str(h5), "--model", "actuator", "--json"]))
    assert js["source"] == SIM and "fit_percent" in js
    out = _run(capsys, ["identify", str(csv), "--model", "actuator"])
    assert out.splitlines()[0].startswith("source: not stated by the record")
    js = json.loads(_run(capsys, ["identify", str(csv), "--model", "actuator", "--json"]))
    assert js["source"] == {"source": None, "drivers": None}


def test_compare_and_diagnose_print_source(files, capsys, tmp_path):
    h5, csv = files
    model = tmp_path / "m.yaml"
    _run(capsys, ["identify", str(h5), "--model", "actuator", "-o", str(model)])
    out = _run(capsys, ["compare", str(model), str(h5)])
    assert out.splitlines()[0] == "source: simulated (drivers: fast sim)"
    assert json.loads(_run(capsys, ["compare", str(model), str(csv), "--json"]))["source"] == {
        "source": None, "drivers": None}
    args = ["--submodel", "actuator", "--no-refit", "--steps", "1"]
    out = _run(capsys, ["diagnose", str(h5), *args])
    assert out.splitlines()[0] == "source: simulated (drivers: fast sim)"
    js = json.loads(_run(capsys, ["diagnose", str(h5), *args, "--json"]))
    assert js["source"] == SIM and "findings" in js


def test_api_results_carry_source(files):
    h5, _ = files
    rec = api.load(h5, range="0:2000")
    assert rec.n == 2000
    idf = api.identify(rec, "actuator")
    assert idf.source == SIM and idf.summary()["source"] == SIM
    assert api.compare(idf, rec).source == SIM


def test_every_simulated_driver_says_so():
    """A simulated plant must never label its records `source: rig`: every registered driver
    named sim* declares `simulated`, the hardware drivers do not."""
    from rigd.driver import available_drivers, data_source, driver_class

    names = available_drivers()
    assert {"sim", "serial", "modbus"} <= set(names)
    for name in names:
        cls = driver_class(name)
        assert cls.simulated is name.startswith("sim"), name
    fake = type("D", (), {"name": "serial", "simulated": False})()
    sim = type("S", (), {"name": "sim", "simulated": True})()
    assert data_source(fake, [])["source"] == "rig"
    assert data_source(fake, [sim]) == {"source": "simulated",
                                        "drivers": {"fast": "serial", "slow": ["sim"]}}
