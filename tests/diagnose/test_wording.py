"""The words layer (rigd/diagnose/wording.py, advice.py, domain.py): every evidence code has
words in every domain; rotor records keep their rotor words and the rig's experiment files;
other records get neither, and advice sized by their own rate and time constants."""

from __future__ import annotations

import re

import numpy as np
import pytest

from rigd.diagnose import advice as A
from rigd.diagnose import domain as D
from rigd.diagnose import wording as W
from rigd.ident.model import LinearPart, Model

DOMAINS = D.DOMAINS
MECH = re.compile("stiffness|resonan|rotor|bearing|film|valve|gyroscop|yaml", re.I)
EVIDENCE = {
    "extra_mode": {"frequency_hz": 0.013, "zeta": 0.05, "model_peaks_hz": [0.004]},
    "cross_coupling": {"output": "y1", "input": "u2", "corr": 0.4, "antisymmetric": True,
                       "omega_hz": 50.0},
    "delay": {"delay_samples": 3.2, "min_samples": 0.5, "input": "u", "delays_samples": [3],
              "fit_points_lost": 0.12, "min_points": 0.5},
    "static_nonlinearity": {"site": "input", "channel": "u1", "bend_at_spread": [0.3]},
    "friction": {"output": "y1", "against_motion": True},
    "integrator": {"in_base": True, "time_constant_s": 900.0, "estimation_seconds": 80.0,
                   "feedback_suspected": True, "input": "u1", "output": "y1"},
    "extra_dynamics": {"time_constant_s": 12.0},
}


@pytest.mark.parametrize("key", sorted(W.TEMPLATES))
@pytest.mark.parametrize("domain", DOMAINS)
def test_every_code_has_words_in_every_domain(key, domain):
    effect, code = key
    ev = dict(EVIDENCE[effect], share=0.42, fs=1.0)
    if code == "lead":
        ev["delay_samples"] = -2.0
    if code.endswith(".output"):
        ev["site"] = "output"
    if code == "static_nonlinearity.input_output":
        ev.update(site="input+output", channels=["u1", "y1"], bend_at_spread=[0.3, 0.1])
    if code == "static_nonlinearity.state":
        ev.update(site="state", channel="y2", signal_share={"u1": 0.2, "y1": 0.1, "y2": 0.7},
                  states=5)
    if code == "integrator.added":
        ev["in_base"] = False
    text = W.explanation(effect, code, ev, domain)
    assert text and "{" not in text
    if effect == "integrator" and ev["in_base"]:  # an explicit integrator: τ = ∞
        inf = W.explanation(effect, code, dict(ev, time_constant_s=float("inf")), domain)
        assert "pole at zero" in inf and "inf" not in inf
    if domain == "process":
        assert not MECH.search(text), text


def test_rotor_keeps_its_words():
    ev = dict(EVIDENCE["cross_coupling"], share=0.3, fs=5000.0)
    assert "gyroscopic" in W.explanation("cross_coupling", "coupling", ev, "rotor")
    assert "gyroscopic" not in W.explanation("cross_coupling", "coupling", ev, "mechanical")
    ev = dict(EVIDENCE["delay"], share=0.3, fs=5000.0)
    assert "valve to film force" in W.explanation("delay", "lag", ev, "rotor")
    assert "resonance" in W.band_near_model([12.0], "mechanical")
    assert not MECH.search(W.band_near_model([0.004], "process"))


def test_advice_names_the_rig_file_only_for_rotor_records_and_sizes_holds():
    ev = {"why": "x", "fs": 1.0, "time_constants_s": [40.0, 3.0]}
    rotor = A.cannot_reveal("creep", "slow", ev, "rotor")[1]
    assert A.ROTOR_MULTILEVEL in rotor and "0.05–0.5 s" in rotor
    for dom in ("mechanical", "process", "generic"):
        for eff, code in (("creep", "slow"), ("hysteresis", "few_levels")):
            text = A.cannot_reveal(eff, code, ev, dom)[1]
            assert "yaml" not in text and "0.05–0.5" not in text, text
    assert "40 s–400 s" in A.cannot_reveal("creep", "slow", ev, "process")[1]
    # at 5 kHz without time constants: 20 samples .. 200 samples
    fast = A.cannot_reveal("creep", "slow", {"why": "x", "fs": 5000.0}, "process")[1]
    assert "4 ms–40 ms" in fast, fast


def test_a_two_input_record_is_never_a_single_axis():
    for nu, ny, want in ((2, 1, "2 inputs but a single output"), (1, 1, "a single input"),
                         (3, 2, "3 inputs and 2 outputs")):
        why, exp = A.cannot_reveal("cross_coupling", "paths", {"nu": nu, "ny": ny}, "process")
        assert want in why and "axis" not in why + exp
    assert A.cannot_reveal("cross_coupling", "paths", {"nu": 1, "ny": 1},
                           "rotor")[0] == "the record has a single axis"


class _Lin(Model):
    """A model that is only its continuous state matrix A."""
    names = ["a"]

    def __init__(self, A):
        self.A = np.asarray(A, float)

    def linear_part(self, theta):
        n = self.A.shape[0]
        return LinearPart(self.A, np.zeros((n, 1)), np.zeros((1, n)), np.zeros((1, 1)))


def test_domain_from_the_poles_and_the_record():
    theta = np.zeros(1)
    light = _Lin([[0, 1], [-(2 * np.pi) ** 2, -2 * 0.02 * 2 * np.pi]])
    heavy = _Lin([[-1 / 40.0, 0], [0, -1 / 3.0]])
    assert D.decide("generic", {}, light, theta).name == "mechanical"
    assert D.decide("generic", {}, heavy, theta).name == "process"
    assert D.decide("generic", {"source": "simulated"}, heavy, theta).name == "rotor"
    assert D.decide("bearing", {}, heavy, theta).name == "rotor"
    assert D.decide("generic", {}, None, None).name == "generic"
    assert D.time_constants(heavy, theta) == pytest.approx([40.0, 3.0])
    from rigd.effects import REGISTRY

    proc = D.decide("generic", {}, heavy, theta)
    offered = {n for n, e in REGISTRY.items() if D.offered(e, proc)}
    assert "cubic_stiffness" not in offered and "runout" not in offered
    # friction is domain-neutral (a sticking actuator of a process too): whether the base
    # can carry it (velocity states) is the base's question, Effect.not_offered
    assert {"friction", "static_nonlinearity", "integrator", "extra_dynamics"} <= offered
    assert {"delay", "extra_mode", "cross_coupling"} <= offered


def test_integrator_words_carry_the_closed_loop_advice():
    ev = dict(EVIDENCE["integrator"], share=0.0, fs=10.0)
    for dom in DOMAINS:
        text = W.explanation("integrator", "integrator.in_base", ev, dom)
        assert "identify it in closed loop" in text and "900 s" in text, text


def test_an_integrating_structure_without_feedback_gets_a_modal_testers_advice():
    """A structure under a shaker whose model integrates (a free rigid-body motion or a
    suspension mode below the band) is told of its suspension, not of a controller; with the
    input seen reacting to the output the closed-loop advice stays; the other domains keep
    it either way."""
    ev = dict(EVIDENCE["integrator"], share=0.0, fs=400.0, feedback_suspected=False)
    text = W.explanation("integrator", "integrator.in_base", ev, "mechanical")
    assert "suspension" in text and "rigid-body" in text, text
    assert "closed loop" not in text and "controller" not in text, text
    for dom in ("rotor", "process", "generic"):
        assert "identify it in closed loop" in W.explanation(
            "integrator", "integrator.in_base", ev, dom)
    ev["feedback_suspected"] = True
    assert "identify it in closed loop" in W.explanation(
        "integrator", "integrator.in_base", ev, "mechanical")


def test_a_band_limited_input_gets_the_broadband_words_of_its_domain():
    """The delay's "no power above 5 % of the sample rate": a rotor record is told of a
    PRBS at the loop rate, a structure of a shaker force over the band or a hammer, a process
    of a PRBS at the sample rate."""
    words = {d: A.cannot_reveal("delay", "no_band", {"share": 0.0, "fs": 400.0,
                                                     "time_constants_s": []}, d)
             for d in DOMAINS}
    assert all("indistinguishable from a gain" in why for why, _ in words.values())
    assert "loop rate" in words["rotor"][1]
    assert "shaker" in words["mechanical"][1] and "PRBS" not in words["mechanical"][1]
    for d in ("process", "generic"):
        assert "sample rate" in words[d][1] and "loop" not in words[d][1], words[d]


def test_a_lag_shorter_than_half_a_sample_is_not_called_a_low_pass():
    """actuator_dynamics' screening words: a lag the record's rate cannot resolve (a
    fraction of a sample) is named as missing high-frequency phase, not a low-pass of
    microseconds on a record sampled every few milliseconds."""
    from types import SimpleNamespace

    from rigd.effects import REGISTRY

    eff = REGISTRY["actuator_dynamics"]
    ctx = SimpleNamespace(fs=400.0, submodel="generic", label=lambda j, kind: f"F{j}")
    short, _ = eff.explain(ctx, SimpleNamespace(beta=np.array([-2.3e-5]), score=0.3))
    assert "low-pass" not in short and "0.0092 samples" in short, short
    assert "high-frequency phase" in short, short
    long_, _ = eff.explain(ctx, SimpleNamespace(beta=np.array([-5e-3]), score=0.3))
    assert "low-pass of about 5 ms" in long_, long_


@pytest.mark.parametrize("key", sorted(A.NEUTRAL))
def test_neutral_entries_cannot_tell_words_sized_by_the_record(key):
    """What the domain-neutral entries cannot tell is worded here from their numbers, the
    durations from the record's rate and the model's time constants (never a rotor file)."""
    effect, code = key
    det = {"absorbed": 0.8, "snr": 0.2, "fit_points": 0.3, "p": 0.3}
    ev = {"nominal_share": 0.1, "min_each_way": 0.1, "detectability": det,
          "record_seconds": 1500.0, "estimation_seconds": 1000.0}
    slow = A.cannot_reveal(effect, code, dict(ev, fs=1.0, time_constants_s=[40.0, 3.0]),
                           "process")
    fast = A.cannot_reveal(effect, code, dict(ev, fs=1000.0, time_constants_s=[0.04]),
                           "mechanical")
    for why, exp in (slow, fast):
        assert why and exp and "{" not in why + exp
        assert not MECH.search(why + exp), (why, exp)
    assert slow[1] != fast[1]  # sized by the record, not a fixed duration
    if code == "too_small":
        assert "80 % of it would be absorbed" in slow[0], slow[0]
    # the slowest time constant (40 s vs 40 ms) sets the holds or periods
    assert ("40 s" in slow[1] or "80 s" in slow[1]) and ("40 ms" in fast[1]
                                                          or "80 ms" in fast[1]), (slow, fast)


def test_runout_not_offered_where_nothing_turns_and_a_cannot_tell_on_the_rotor():
    """A structure under a shaker has no angle channel: run-out (locked to a rotating part's
    angle) is not offered, with the reason in the notes (no advice to record an angle); a
    record that carries an angle is offered it; on the rotor's records a missing encoder
    angle is left to run-out's "cannot tell" with the rotor's experiment."""
    from rigd.diagnose import selection as S
    from rigd.ident.iddata import IdData
    from rigd.ident.lti.statespace import StateSpaceModel

    n, fs = 400, 400.0
    t = np.arange(n) / fs
    u, y = np.sin(2 * np.pi * 7 * t)[:, None], np.cos(2 * np.pi * 7 * t)[:, None]
    m = StateSpaceModel(["force"], ["acc1"], fs, n_complex=1, hold="foh", feedthrough=True)
    mech = D.Domain("mechanical", "a lightly damped mode")
    bare = IdData(u, y, fs, ["force"], ["acc1"])
    turning = IdData(u, y, fs, ["force"], ["acc1"], aux={"phi": 2 * np.pi * 3 * t})
    est = slice(0, 2 * n // 3)
    notes: list[str] = []
    names = S.offered(None, "generic", mech, m, est, n, notes, bare)
    assert "runout" not in names
    (why,) = [x for x in notes if x.startswith("runout not offered: ")]
    assert "nothing in the record turns" in why and "record" not in why.split("turns")[1]
    assert "runout" in S.offered(None, "generic", mech, m, est, n, [], turning)
    rotor = D.Domain("rotor", "the rig's bearing")
    assert "runout" in S.offered(["runout"], "bearing", rotor, m, est, n, [], bare)
