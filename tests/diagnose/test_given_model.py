"""``rigd diagnose --model M.yaml DATA``: a model fitted at one force level, diagnosed on a
record at another. The model is the base, not refitted; what moves when its structure is
refitted here is said in words, for the modes the input excites only.

Records: the jointed-structure generator (tests/gen/joint.py: a bolted joint in the load path
of one mode; that mode softens and damps more with amplitude), of another seed, joint mode
and levels than the mode-site tests use."""

import json
import re

import pytest

from rigd.cli import main
from tests.gen import joint

MODES = joint.FIVE_MODES[:3]
JOINT_MODE = 1      # the second mode carries the joint
BAND = (3.0, 40.0)  # the generator's multisine band, Hz
SEED = 12           # the structure's (its modes' shapes), the multisine's and the noise's


def _record(tmp, level, seed):
    g = joint.joint_structure(level=level, modes=MODES, n=2048, periods=2, n_outputs=1,
                              seed=seed, joint_mode=JOINT_MODE)
    return g, g.write_csv(tmp / f"joint-{level:g}-{seed}.csv")


@pytest.fixture(scope="module")
def low_level_model(tmp_path_factory):
    """An LTI model (three modes: 6 states) identified at force level 0.3 (the joint
    stuck: the structure behaves linearly)."""
    tmp = tmp_path_factory.mktemp("given")
    g, path = _record(tmp, 0.3, seed=SEED)
    opts = ["--fs", str(g.fs), "--inputs", ",".join(g.inputs), "--outputs",
            ",".join(g.outputs)]
    model = tmp / "low.yaml"
    assert main(["identify", str(path), *opts, "--method", "oe", "--order", "6",
                 "-o", str(model)]) == 0
    return tmp, opts, model


def _diagnose(capsys, *args):
    capsys.readouterr()
    assert main(["diagnose", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_at_a_higher_force_level_the_joint_mode_is_said_to_soften_and_damp(
        low_level_model, capsys, tmp_path):
    tmp, opts, model = low_level_model
    g, path = _record(tmp_path, 3.0, seed=SEED)    # 10x the force: the joint slips
    out = _diagnose(capsys, path, *opts, "--model", model, "--effects", "joint", "--steps", 1)
    given = out["given_model"]["generic"]
    assert given["fit_percent_refitted"] > given["fit_percent_given"] + 5.0, given
    assert given["input_level_ratio"] == pytest.approx(10.0, rel=0.05)
    f_joint = MODES[JOINT_MODE][0]
    moved = [m for m in given["modes"] if m["moved"]]
    near = [m for m in moved if abs(m["model_hz"] / f_joint - 1) < 0.2]
    assert near, given["modes"]
    assert near[0]["here_hz"] < near[0]["model_hz"] and near[0]["here_zeta"] > near[0][
        "model_zeta"], near
    assert "amplitude-dependent stiffness and damping" in given["text"]
    # nothing is said of modes the multisine does not excite
    assert all(BAND[0] <= m["model_hz"] <= BAND[1] for m in given["modes"]), given["modes"]
    # what the model misses here: the joint, at that mode
    top = out["findings"][0]
    assert top["effect"] == "joint" and top["significant"], out["findings"][:3]
    at = re.search(r"at the ([0-9.]+) Hz mode", top["explanation"])
    assert at and abs(float(at.group(1)) / near[0]["model_hz"] - 1) < 0.05, top["explanation"]
    # the base is the given model, not a fit of this record
    assert out["fit_percent"] == pytest.approx(given["fit_percent_given"], abs=0.01)


def test_below_the_slip_the_parameters_carry(low_level_model, capsys, tmp_path):
    tmp, opts, model = low_level_model
    g, path = _record(tmp_path, 0.15, seed=SEED)   # half the force: still stuck
    out = _diagnose(capsys, path, *opts, "--model", model, "--no-refit")
    given = out["given_model"]["generic"]
    assert "its parameters carry to this record" in given["text"], given["text"]
    assert given["fit_percent_given"] > 80.0
    assert "amplitude-dependent" not in given["text"]


def test_a_model_of_other_channels_is_refused_in_one_line(low_level_model, capsys, tmp_path):
    tmp, opts, model = low_level_model
    g, path = _record(tmp_path, 0.15, seed=SEED)
    other = ["--fs", str(g.fs), "--inputs", ",".join(g.inputs), "--outputs", "t"]
    capsys.readouterr()
    assert main(["diagnose", str(path), *other, "--model", str(model)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "outputs" in err and str(model) in err
    assert main(["diagnose", str(path), *opts, "--model", str(model), "--init",
                 str(model)]) == 2
    assert "use one of them" in capsys.readouterr().err


def test_an_effect_the_base_cannot_carry_is_said_in_the_terminal(low_level_model, capsys,
                                                                 tmp_path):
    """Not only on the report page: the terminal says which effect was not tried and why (a
    cubic stiffness needs a mechanical base; the given model is a modal LTI one)."""
    tmp, opts, model = low_level_model
    g, path = _record(tmp_path, 0.15, seed=SEED)
    capsys.readouterr()
    assert main(["diagnose", str(path), *opts, "--model", str(model), "--effects",
                 "cubic_stiffness", "--no-refit"]) == 0
    out = capsys.readouterr().out
    line = next((ln for ln in out.splitlines() if "not tried:" in ln), "")
    assert "cubic_stiffness not offered" in line and "mechanical" in line, out
