"""Delay first, then order (rigd.ident.lti.order.choose_base) on independently simulated
records (tests/gen: scipy/numpy only, never rigd's own models)."""

from __future__ import annotations

import numpy as np
import pytest

from rigd.ident.iddata import IdData
from rigd.ident.lti.order import OrderRefused, choose_base
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import fit, fit_percent
from rigd.ident.readouts import linear_readouts
from tests.gen.linear import THREE_MODES, integrator_loop, structure_2in_3modes, thermal


def _split(g):
    d = IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))
    k = int(round(2 * d.n / 3))
    return d, slice(0, k), slice(k, d.n)


def test_two_input_three_mode_structure_gets_its_three_modes():
    g = structure_2in_3modes(seed=3, n=4000)
    d, est, val = _split(g)
    c = choose_base(d, est, val, hold="zoh")
    ro = linear_readouts(c.structure.linear_part(c.theta))
    got = sorted(m["f_n_hz"] for m in ro["modes"] if "f_n_hz" in m)
    assert c.family == "lti" and c.modes == 3 and c.states == 6
    assert got == pytest.approx([f for f, _ in THREE_MODES], rel=0.02)
    # within 1 point of the true-order model fitted from the truth's poles
    true = StateSpaceModel(d.input_names, d.output_names, d.fs, n_complex=3, hold="zoh")
    true.set_record(est.stop)
    lam = [complex(p) for p in g.truth["poles"] if complex(p).imag > 0]
    from rigd.ident.lti.modal import gains_by_least_squares

    th = fit(true, d.slice(0, est.stop), method="oe",
             theta0=gains_by_least_squares(true, lam, d.slice(0, est.stop))).theta
    f_true = fit_percent(d.y[val], true.simulate(th, d)[val]).mean()
    f_got = fit_percent(d.y[val], c.structure.simulate(c.theta, d)[val]).mean()
    assert f_got >= f_true - 1.0


def test_heater_with_a_three_sample_delay_is_first_order_with_that_delay():
    g = thermal(delay=3.0, tau_s=40.0, n=2400, seed=5)
    d, est, val = _split(g)
    c = choose_base(d, est, val, hold="zoh")
    assert c.states == 1 and abs(c.delays[0] - 3) <= 1
    ro = c.structure.readouts(c.theta)
    tau = [m["time_constant_s"] for m in ro["modes"] if "time_constant_s" in m]
    assert tau == pytest.approx([40.0], rel=0.1)
    assert ro["static_gain"][0][0] == pytest.approx(0.6, rel=0.05)
    js = c.to_json()
    assert js["family"] in ("lti", "process") and js["delays_samples"] == c.delays


@pytest.mark.parametrize("seed", [2, 4])
def test_a_heater_fitted_with_the_other_hold_gets_no_integrator_it_does_not_need(seed):
    # held steps fitted as if linear between samples (foh): half a sample of lag to carry,
    # which a spare state can take; a slow real pole read as an integrator whose gain the
    # refit then drives to nothing must not survive as "a pole at zero, static gain inf"
    g = thermal(delay=3.0, tau_s=20.0, fs=2.0, n=1500, seed=seed)
    d, est, val = _split(g)
    c = choose_base(d, est, val, hold="foh")
    ro = c.structure.readouts(c.theta)
    assert ro["integrators"] == 0
    assert ro["static_gain"][0][0] == pytest.approx(0.6, rel=0.1)
    slow = max(m["time_constant_s"] for m in ro["modes"] if "time_constant_s" in m)
    assert slow == pytest.approx(20.0, rel=0.15)


def test_an_integrating_plant_gets_an_integrator_not_a_spring():
    g = integrator_loop("PI", n=3000, seed=2)
    d, est, val = _split(g)
    c = choose_base(d, est, val, hold="zoh")
    ro = c.structure.readouts(c.theta)
    assert ro["integrators"] == 1 and ro["static_gain"] == [[None]]
    # the plant's own lag (τ = 0.05 s) beside the integrator
    taus = [m["time_constant_s"] for m in ro["modes"] if "time_constant_s" in m]
    assert any(abs(t - g.truth["plant"]["tau_s"]) < 0.2 * g.truth["plant"]["tau_s"]
               for t in taus)


def test_order_n_is_fitted_exactly_or_refused_with_the_reason():
    g = thermal(delay=2.0, tau_s=20.0, n=1500, seed=7)
    d, est, val = _split(g)
    for n in (1, 3, 4):
        c = choose_base(d, est, val, order=n, hold="zoh")
        assert c.states == n == c.structure.nx and c.asked == n
    with pytest.raises(OrderRefused, match="at most 30 states"):
        choose_base(d, est, val, order=31, hold="zoh")
    with pytest.raises(OrderRefused, match="supports at most"):
        choose_base(IdData(d.u[:300], d.y[:300], d.fs, d.input_names, d.output_names),
                    slice(0, 200), slice(200, 300), order=25, hold="zoh")
    with pytest.raises(OrderRefused, match="at least 1 state"):
        choose_base(d, est, val, order=0)


def test_a_model_file_rebuilds_the_chosen_family(tmp_path):
    from rigd.ident.modelfile import ModelFile, Submodel, load_model

    g = thermal(delay=3.0, tau_s=30.0, n=1500, seed=1)
    d, est, val = _split(g)
    c = choose_base(d, est, val, order=2, hold="foh")
    sm = Submodel("generic", c.structure, c.theta, np.zeros_like(c.theta), "oe")
    path = ModelFile(d.fs, {"generic": sm}).save(tmp_path / "m.yaml")
    back = load_model(path).submodels["generic"]
    assert np.allclose(back.structure.simulate(back.theta, d), c.structure.simulate(c.theta, d))


def test_scan_scores_a_validation_part_before_the_estimation_part():
    """Silverbox's split (validation first): the scan's held-out fit is a free run from rest
    on the validation samples, not −inf (no LTI candidate was left before)."""
    from rigd.ident.lti.scan import scan_orders

    g = structure_2in_3modes(seed=2, n=3000)
    d = IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))
    pts = scan_orders(d, slice(1000, 3000), slice(0, 1000), (0, 0), 8, orders=[6])
    assert len(pts) == 1 and pts[0].fit_val > 80.0
