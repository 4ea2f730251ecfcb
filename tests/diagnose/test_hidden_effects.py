"""Must-show: each catalogue effect hidden in the simulated rig is ranked first, significant,
and adding it cuts the error (100 − fit) at least 3×; no hidden effect -> nothing significant;
two hidden effects -> both found and each added one lowers the error."""

import numpy as np
import pytest

import plant  # tests/diagnose/plant.py
from rigd.diagnose.engine import diagnose_data
from rigd.ident.greybox.mechanical import MechanicalStructure
from rigd.ident.greybox.submodels import structure_for


def decoupled_bearing():
    eye = np.eye(2, dtype=bool)
    return MechanicalStructure("bearing", eye, eye, eye, eye, "", ["x", "y"], ["x", "y"],
                               ["u_x", "u_y"], ["e_x", "e_y"])


def held(sub, data):
    """The private rig holds its inputs over each sample (ZOH), so its base model does too."""
    return structure_for(sub, data, hold="zoh")


def _data(effect, seed=0):
    if effect in ("hysteresis", "creep"):
        d = plant.actuator([effect], seed=seed)
        return d, "actuator", held("actuator", d)
    d = plant.bearing([effect], seed=seed)
    s = decoupled_bearing() if effect == "cross_coupling" else held("bearing", d)
    return d, "bearing", s


# Fast unit-level checks on the private rig (an open-loop valve pair: no recorded drives, so
# hysteresis and creep act on the input itself). The must-show tests run on the project's
# plant (test_diagnose_plant.py), hysteresis and creep inside the PD valve loops included.
@pytest.mark.parametrize("effect", ["hysteresis", "creep", "cubic_stiffness"])
def test_hidden_effect_ranked_first_and_error_falls(effect):
    data, sub, s = _data(effect)
    sd = diagnose_data(data, sub, structure=s)
    top = sd.findings[0]
    assert top.effect == effect, [(f.effect, f.score) for f in sd.findings]
    assert top.significant
    assert (100 - sd.fit_percent) >= 3 * (100 - top.fit_percent_with)
    assert effect.split("_")[0] in top.explanation or top.explanation  # plain text present


@pytest.mark.parametrize("pair", [("cubic_stiffness", "runout")])
def test_two_hidden_effects_forward_selection_private_rig(pair):
    """Unit-level check on the private rig (the must-show one uses the project's plant)."""
    data = plant.bearing(list(pair), seed=3)
    sd = diagnose_data(data, "bearing", structure=held("bearing", data))
    assert {f.effect for f in sd.findings if f.significant} == set(pair)
    fits = [s.fit_percent for s in sd.steps]
    assert [s.added for s in sd.steps[1:]] and set(s.added for s in sd.steps[1:]) == set(pair)
    assert all(b > a for a, b in zip(fits, fits[1:])), fits


def test_runout_invisible_at_standstill_is_listed():
    d = plant.bearing([], seed=1, seconds=1.0)
    sd = diagnose_data(d, "bearing", structure=held("bearing", d))
    assert any(c.effect == "runout" and c.experiment for c in sd.cannot_reveal)


def test_two_level_input_cannot_reveal_hysteresis():
    d = plant.actuator(["hysteresis"], seed=2, seconds=1.0)
    d = d.with_inputs(np.sign(d.inputs + 1e-9))
    sd = diagnose_data(d, "actuator", refit=False)
    c = [c for c in sd.cannot_reveal if c.effect == "hysteresis"]
    assert c and "multi-level" in c[0].experiment
