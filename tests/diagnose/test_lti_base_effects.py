"""Effects on a general LTI base (rigd.ident.lti.statespace.StateSpaceModel): what needs a
mechanical base is not offered and says why, what the base already carries (a delay, an
integrator) is named from it, and nothing reads the LTI model's modal states as [p, ṗ]."""

from __future__ import annotations

import numpy as np
import pytest

from rigd.diagnose import wording as W
from rigd.effects import REGISTRY
from rigd.effects.base import is_mechanical
from rigd.effects.context import Context
from rigd.ident.greybox.mechanical import generic_structure
from rigd.ident.iddata import IdData
from rigd.ident.lti.statespace import StateSpaceModel

FS = 100.0
N = 1500


def _lti(delays=(0, 3), n_int=0):
    """Two inputs, one output: one mode at 4 Hz (ζ 0.1), one real pole (or integrator)."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal((N, 2))
    m = StateSpaceModel(["a", "b"], ["y"], FS, n_complex=1, n_real=0 if n_int else 1,
                        n_int=n_int, delays=list(delays), hold="zoh")
    m.set_record(1000)
    wn = 2 * np.pi * 4.0
    lam = [complex(-0.1 * wn, wn * np.sqrt(1 - 0.01))]
    lam += [0j] if n_int else [complex(-2 * np.pi * 1.0, 0)]
    th = m.pack(lam, np.ones((3, 2)), np.array([[1.0, 0.0, 1.0]]))
    d0 = IdData(u, np.zeros((N, 1)), FS, ["a", "b"], ["y"])
    y = np.asarray(m.simulate(th, d0))
    d = IdData(u, y, FS, ["a", "b"], ["y"])
    return d, m, th, y


def _ctx(d, m, th, y):
    return Context("generic", d, m, th, y, slice(0, 1000), slice(1000, N),
                   input_names=["a", "b"], output_names=["y"])


def test_continuous_is_the_linear_part_and_not_mechanical():
    d, m, th, _ = _lti()
    A, B, C, D, x0 = m.continuous(th)
    lp = m.linear_part(th)
    for a, b in ((A, lp.A), (B, lp.B), (C, lp.C), (D, lp.D)):
        assert np.array_equal(a, b)
    assert x0.shape == (m.nx,)
    assert not is_mechanical(m)
    assert not is_mechanical(REGISTRY["delay"].extend(m))
    mech = generic_structure(["a", "b"], ["y"])
    assert is_mechanical(mech) and is_mechanical(mech.with_modes(1))
    assert is_mechanical(REGISTRY["delay"].extend(mech))


@pytest.mark.parametrize("name", ["cubic_stiffness", "hysteresis_restoring", "friction"])
def test_state_level_effects_not_offered_on_an_lti_base_with_the_reason(name):
    _, m, _, _ = _lti()
    why = REGISTRY[name].not_offered(m)
    assert why is not None and name in why and "mechanical" in why and "lti" in why
    assert REGISTRY[name].not_offered(generic_structure(["a", "b"], ["y"])) is None
    # input- and output-level effects sit on any base
    assert REGISTRY["delay"].not_offered(m) is None


def test_through_force_on_an_lti_base_is_the_response_to_the_input():
    """The force regressor of a restoring-force effect reads [p, ṗ] states: on an LTI base
    (modal states) it falls back to the response through the input."""
    d, m, th, y = _lti(delays=(0, 0))
    ctx = _ctx(d, m, th, y)
    v = np.sin(np.arange(N) / 7.0)
    assert np.allclose(ctx.through_force(v, 0), ctx.through_model(v, 0))


def test_a_delay_in_the_base_is_named_from_it():
    d, m, th, y = _lti(delays=(0, 3))
    f = REGISTRY["delay"].carried_by_base(_ctx(d, m, th, y))
    assert f is not None and f.effect == "delay" and f.significant
    ev = f.evidence
    assert ev["code"] == "delay.in_base" and ev["delay_samples"] == 3.0
    assert ev["delays_samples"] == [0, 3] and ev["input"] == "b"
    assert ev["delay_ms"] == pytest.approx(30.0)
    text = W.explanation("delay", ev["code"], dict(ev, share=0.0, fs=FS), "process")
    assert "3 samples" in text and "b" in text
    # no delay in the base: nothing named from it
    d, m, th, y = _lti(delays=(0, 0))
    assert REGISTRY["delay"].carried_by_base(_ctx(d, m, th, y)) is None


@pytest.mark.parametrize("lost,named", [(0.2, False), (-3.0, False), (0.5, True),
                                        (12.0, True)])
def test_a_delay_in_the_base_is_named_only_when_the_data_pay_for_it(lost, named):
    """rigd.diagnose.selection.carried: a delay the base carries is significant only when
    the base refitted without it loses at least MIN_FIT_GAIN held-out points; otherwise it
    is listed with the reason (it stands in for a lag of the dynamics)."""
    from rigd.diagnose import domain as D
    from rigd.diagnose.selection import carried

    d, m, th, y = _lti(delays=(0, 3))
    dom = D.decide("generic", {}, m, th)
    f, = carried(_ctx(d, m, th, y), ["delay"], dom, {"delay": lost})
    assert f.significant is named and f.evidence["fit_points_lost"] == lost
    assert f.evidence["code"] == ("delay.in_base" if named else "delay.in_base_not_paid")
    assert ("not a transport delay" in f.explanation) is not named, f.explanation
    assert "3 samples" in f.explanation and f"{max(lost, 0):.2f} points worse" in f.explanation
    # without a measure of its worth the delay is named from the base as before
    f, = carried(_ctx(d, m, th, y), ["delay"], dom)
    assert f.significant and "fit_points_lost" not in f.evidence


def test_an_integrator_in_an_lti_base_is_named_from_it():
    """rigd.effects.integrator reads the base's poles through ``continuous``: an LTI base
    with an explicit integrator is named an integrating plant."""
    d, m, th, y = _lti(delays=(0, 0), n_int=1)
    f = REGISTRY["integrator"].carried_by_base(_ctx(d, m, th, y))
    assert f is not None and f.evidence["code"] == "integrator.in_base"
