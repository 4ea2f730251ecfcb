"""Experiment YAML: strict validation with file:line: key: problem."""

import pytest

from rigd.errors import InputError
from rigd.experiments.schemas import ImpactSpec, PrbsSpec, RunoutSpec, SweepSpec, load_experiment

GOOD_PRBS = """\
kind: prbs
name: prbs-test
operating_point: {omega_rpm: 0, p_inj_bar: 4.0}
amplitude_v: [1.0, 0.5]
switch_probability: 0.2
min_hold_s: 0.001
seed: 3
duration_s: 0.5
lead_in_s: 0.1
"""

# name -> (yaml text, line, words in the message)
BAD = {
    "unknown_kind": ("kind: wobble\nduration_s: 1\n", 1, "unknown kind 'wobble'"),
    "missing_kind": ("duration_s: 1\n", 1, "missing key 'kind'"),
    "unknown_key": (GOOD_PRBS + "colour: red\n", 10, "colour: unknown key"),
    "negative_amplitude": (GOOD_PRBS.replace("[1.0, 0.5]", "-1"), 4, "amplitude_v"),
    "amplitude_too_big": (GOOD_PRBS.replace("[1.0, 0.5]", "[1.0, 20]"), 4, "within [0, 10] V"),
    "wrong_type": (GOOD_PRBS.replace("duration_s: 0.5", "duration_s: long"), 8,
                   "duration_s: Input should be a valid number"),
    "missing_duration": (GOOD_PRBS.replace("duration_s: 0.5\n", ""), None,
                         "duration_s: Field required"),
    "probability_out_of_range": (GOOD_PRBS.replace("0.2", "1.5"), 5, "switch_probability"),
    "not_yaml": ("kind: prbs\n  amplitude_v: [1,\n", None, "not valid YAML"),
    "empty": ("", None, "file is empty"),
    "not_a_mapping": ("- kind: prbs\n", 1, "expected a mapping"),
    "impact_bad_axis": ("kind: impact\naxis: z\n", 2, "axis"),
    "runout_standing_shaft": ("kind: runout\noperating_point: {omega_rpm: 0, p_inj_bar: 4}\n",
                              None, "turning shaft"),
    "multisine_band": ("kind: multisine\namplitude_v: 1\nf_min_hz: 100\nf_max_hz: 10\n"
                       "period_s: 1\n", None, "must exceed f_min_hz"),
    "sweep_bad_point_key": ("kind: sweep\ngrid: {omega_rpm: [0], p_inj_bar: [3, 4]}\n"
                            "at_each:\n  kind: prbs\n  amplitude_v: 1\n  duration_s: 1\n"
                            "  bogus: 2\n", 7, "at_each.bogus: unknown key"),
    "sweep_point_kind": ("kind: sweep\ngrid: {omega_rpm: [0], p_inj_bar: [4]}\n"
                         "at_each:\n  kind: sweep\n", 4, "at_each.kind"),
    "sweep_repeated_grid": ("kind: sweep\ngrid:\n  omega_rpm: [0, 0]\n  p_inj_bar: [4]\n"
                            "at_each: {kind: runout}\n", 3, "repeated"),
    "sweep_runout_at_zero": ("kind: sweep\ngrid:\n  omega_rpm: [0, 3000]\n  p_inj_bar: [4]\n"
                             "at_each: {kind: runout}\n", 3, "omega_rpm > 0"),
    "sweep_point_op": ("kind: sweep\ngrid: {omega_rpm: [0], p_inj_bar: [4]}\n"
                       "at_each:\n  kind: prbs\n  amplitude_v: 1\n  duration_s: 1\n"
                       "  operating_point: {omega_rpm: 0, p_inj_bar: 4}\n", 7,
                       "at_each.operating_point"),
}


def test_good_prbs(tmp_path):
    p = tmp_path / "e.yaml"
    p.write_text(GOOD_PRBS)
    spec, point, text = load_experiment(p)
    assert isinstance(spec, PrbsSpec) and point is None
    assert spec.amplitude_v == [1.0, 0.5] and spec.axes == ["x", "y"] and not spec.controller


def test_good_impact_and_sweep(tmp_path):
    p = tmp_path / "i.yaml"
    p.write_text("kind: impact\naxis: y\ncontroller: [off, on]\nrepeats: 2\n")
    spec, _, _ = load_experiment(p)
    assert isinstance(spec, ImpactSpec) and spec.controller == [False, True]
    p.write_text("kind: sweep\ngrid: {omega_rpm: [1000, 2000], p_inj_bar: [3, 4, 5]}\n"
                 "at_each: {kind: runout, revolutions: 20}\n")
    spec, point, _ = load_experiment(p)
    assert isinstance(spec, SweepSpec) and isinstance(point, RunoutSpec)
    assert [(o.omega_rpm, o.p_inj_bar) for o in spec.points()][:4] == [
        (1000, 3), (1000, 4), (1000, 5), (2000, 3)]


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_experiment_refused(tmp_path, name):
    text, line, words = BAD[name]
    p = tmp_path / f"{name}.yaml"
    p.write_text(text)
    with pytest.raises(InputError) as info:
        load_experiment(p)
    msg = str(info.value)
    assert "\n" not in msg and words in msg, msg
    assert msg.startswith(f"{p}:{line}:" if line else f"{p}"), msg
