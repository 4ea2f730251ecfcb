"""A controller that is unstable in closed loop, at the wrong rate or of the wrong size never
reaches the loop: refused by load_controller, by ControlLoop.load_controller and by
``rigd run --controller`` (exit 2)."""

import numpy as np
import pytest
import yaml

from rigd.cli import main
from rigd.controller import load_controller
from rigd.errors import InputError


@pytest.fixture(scope="module")
def good(truth_design):
    """The controller ``rigd design`` made for the simulated plant's truth (made once per test
    run: tests/conftest.py ``truth_design``)."""
    return truth_design / "controller.yaml"


def _variant(good, tmp_path, name, edit):
    doc = yaml.safe_load(good.read_text())
    edit(doc)
    p = tmp_path / name
    p.write_text(yaml.safe_dump(doc))
    return p


def _flip_sign(doc):           # positive feedback: K(z) stable, closed loop unstable
    doc["C"] = (-np.array(doc["C"])).tolist()
    doc["D"] = (-np.array(doc["D"])).tolist()


def _high_gain(doc):
    doc["C"] = (40 * np.array(doc["C"])).tolist()
    doc["D"] = (40 * np.array(doc["D"])).tolist()


def _wrong_rate(doc):
    doc["fs_hz"] = 2500.0


def _wrong_dims(doc):
    doc["B"] = [row + [0.0] for row in doc["B"]]      # 3 inputs


BAD = [("unstable_cl.yaml", _flip_sign, "closed loop"),
       ("high_gain.yaml", _high_gain, "closed loop"),
       ("rate.yaml", _wrong_rate, "rate"),
       ("dims.yaml", _wrong_dims, "B must be")]


def test_good_controller_loads(good):
    c = load_controller(good, expected_fs_hz=5000.0)
    assert c.order >= 4 and np.max(np.abs(np.linalg.eigvals(c.A))) < 1


@pytest.mark.parametrize("name,edit,msg", BAD)
def test_load_controller_refuses(good, tmp_path, name, edit, msg):
    bad = _variant(good, tmp_path, name, edit)
    with pytest.raises(InputError, match=msg) as ei:
        load_controller(bad, expected_fs_hz=5000.0)
    assert name in str(ei.value)


@pytest.mark.parametrize("name,edit,msg", BAD[:1] + BAD[2:])
def test_control_loop_refuses_and_keeps_running_controller(good, tmp_path, name, edit, msg):
    from rigd.loop.app import build_loop

    bad = _variant(good, tmp_path, name, edit)
    loop = build_loop("config/sim.yaml", clock="lockstep", controller=good)
    with loop:
        before = loop.controller
        with pytest.raises(InputError, match=msg):
            loop.load_controller(bad)
        loop.run_for(0.01)
        assert loop.controller is before


@pytest.mark.parametrize("name,edit,msg", BAD[:1] + BAD[2:])
def test_rigd_run_controller_exit_2(good, tmp_path, capsys, name, edit, msg):
    bad = _variant(good, tmp_path, name, edit)
    rc = main(["run", "--config", "config/sim.yaml", "--lockstep", "--duration", "0.01",
               "--controller", str(bad)])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and name in err[0]
