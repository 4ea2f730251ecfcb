"""Exact output sensitivities of the general LTI model (rigd.ident.lti.sensitivity) and the
fit's Jacobian that uses them (rigd.ident.jacobian): each column is the model's own forward
difference, and a fit takes the steps of the all-difference Jacobian."""

from __future__ import annotations

import numpy as np
import pytest

from rigd.ident.iddata import IdData
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import fit


def _model(hold, nc, nr, ni, feedthrough, delays):
    m = StateSpaceModel(["a", "b"], ["y1", "y2"], 100.0, nc, nr, ni, delays=delays, hold=hold,
                        feedthrough=feedthrough,
                        norm_rows=[k % 2 for k in range(nc + nr + ni)])
    m.set_record(1000)
    return m


def _theta(m, rng):
    th = 0.3 * rng.standard_normal(len(m.names))
    th[0:2 * m.nc:2] = np.log(rng.uniform(0.01, 0.2, m.nc))
    th[1:2 * m.nc:2] = rng.uniform(0.05, 0.5, m.nc)
    th[2 * m.nc:2 * m.nc + m.nr] = np.log(rng.uniform(0.01, 0.1, m.nr))
    return th


def _assert_columns_are_differences(model, th, d, idx, dY):
    """Each sensitivity column dY[k] is the central difference of ``model.simulate`` in
    parameter ``idx[k]`` (exact for the parameters the output is linear in; to the
    difference's own error, ~h², for the poles)."""
    for k, p in enumerate(idx):
        h = 1e-5 * max(1.0, abs(th[p]))
        t1, t2 = th.copy(), th.copy()
        t1[p] += h
        t2[p] -= h
        fd = (model.simulate(t1, d) - model.simulate(t2, d)) / (2 * h)
        assert np.max(np.abs(fd - dY[k])) <= 1e-6 * max(np.max(np.abs(fd)), 1.0), \
            model.names[p]


@pytest.mark.parametrize("hold", ["zoh", "foh"])
@pytest.mark.parametrize("nc,nr,ni,feedthrough,delays",
                         [(2, 1, 1, True, [0, 2]), (1, 0, 0, False, [1, 0])])
def test_each_sensitivity_is_the_forward_difference_of_the_simulation(hold, nc, nr, ni,
                                                                      feedthrough, delays):
    rng = np.random.default_rng(3)
    m = _model(hold, nc, nr, ni, feedthrough, delays)
    th = _theta(m, rng)
    d = IdData(rng.standard_normal((1000, 2)), np.zeros((1000, 2)), 100.0, ["a", "b"],
               ["y1", "y2"])
    idx, dY = m.output_sensitivities(th, d)
    # every parameter of the simulated output has its column (K, the noise model's, is the
    # predictor's only): the poles by the sensitivity equations, the others exactly
    assert {m.names[i] for i in idx} == {v for v in m.names if v[0] != "k"}
    lin = {m.names[i][0] for i in idx}
    assert ("d" in lin) == feedthrough and ("r" in lin) == (nr > 0)
    _assert_columns_are_differences(m, th, d, idx, dY)


def test_a_fit_with_the_exact_columns_reaches_the_difference_fits_optimum(monkeypatch):
    rng = np.random.default_rng(0)
    n = 1500
    u = rng.standard_normal((n, 2))
    m = _model("foh", 2, 1, 0, False, [0, 1])
    th = _theta(m, rng)
    d0 = IdData(u, np.zeros((n, 2)), 100.0, ["a", "b"], ["y1", "y2"])
    y = m.simulate(th, d0) + 0.05 * rng.standard_normal((n, 2))
    d = IdData(u, y, 100.0, ["a", "b"], ["y1", "y2"])
    th0 = th * (1 + 0.1 * rng.standard_normal(th.size))
    exact = fit(m, d, method="oe", theta0=th0)
    monkeypatch.delattr(StateSpaceModel, "output_sensitivities")
    diff = fit(m, d, method="oe", theta0=th0)
    # the pole columns differ from forward differences by the differences' error (~1e-6):
    # the steps may differ that little, the optimum and its spread not
    assert exact.info["success"] and diff.info["success"]
    assert exact.cost == pytest.approx(diff.cost, rel=1e-6)
    np.testing.assert_allclose(exact.theta, diff.theta, rtol=1e-3, atol=1e-5)
    np.testing.assert_allclose(exact.std, diff.std, rtol=1e-3)


def test_offsets_column_of_a_mechanical_base_with_a_state_effect_but_not_an_output_one():
    from rigd.effects import REGISTRY
    from rigd.ident.greybox.mechanical import generic_structure
    from rigd.ident.jacobian import additive_offsets

    base = generic_structure(["u"], ["y"])
    cubic = REGISTRY["cubic_stiffness"].extend(base)
    assert additive_offsets(cubic) == [base.names.index("yoff_1")]
    assert additive_offsets(REGISTRY["extra_dynamics"].extend(base)) == []
    rng = np.random.default_rng(2)
    n = 1500
    u = rng.standard_normal((n, 1))
    th = base.theta0(IdData(u, rng.standard_normal((n, 1)), 100.0, ["u"], ["y"]))
    th = np.concatenate([[4.0, 400.0, 400.0, 0.0, 0.0, 0.0, 0.3]
                         if len(th) == 7 else th, [0.0] * (len(cubic.names) - len(th))])
    th[len(base.names):] = 50.0
    d0 = IdData(u, np.zeros((n, 1)), 100.0, ["u"], ["y"])
    y = cubic.simulate(th, d0) + 0.01 * rng.standard_normal((n, 1))
    d = IdData(u, y, 100.0, ["u"], ["y"])
    th0 = th * (1 + 0.05 * rng.standard_normal(th.size))
    import rigd.ident.jacobian as J

    exact = fit(cubic, d, method="oe", theta0=th0)
    saved = J.additive_offsets
    try:
        J.additive_offsets = lambda s: []
        diff = fit(cubic, d, method="oe", theta0=th0)
    finally:
        J.additive_offsets = saved
    assert exact.nfev == diff.nfev
    assert exact.cost == pytest.approx(diff.cost, rel=1e-8)
    # the initial positions are barely determined (the rounding of a column moves them)
    np.testing.assert_allclose(exact.theta, diff.theta, rtol=1e-3, atol=1e-5)


@pytest.mark.parametrize("effects", [["creep"], ["extra_mode"], ["delay", "extra_dynamics"],
                                     ["integrator", "hysteresis"]])
def test_an_lti_base_with_input_and_parallel_effects_keeps_its_exact_columns(effects):
    """The base's linear parameters stay exact through effects on its inputs and effects that
    add a parallel path (rigd.effects.compose.Composed.output_sensitivities): each column is
    the composed model's own forward difference; the effects' parameters are not among them."""
    from rigd.effects import REGISTRY
    from rigd.effects.compose import compose

    rng = np.random.default_rng(5)
    n, fs = 1500, 100.0
    m = StateSpaceModel(["a"], ["y"], fs, 1, 1, 0, hold="foh", feedthrough=True)
    m.set_record(n)
    d = IdData(rng.standard_normal((n, 1)), rng.standard_normal((n, 1)), fs, ["a"], ["y"])
    c = compose(m, [REGISTRY[e] for e in effects])
    th = c.theta0(d)
    th[:len(m.names)] = _theta(m, rng)
    th[len(m.names):] += 0.05 * rng.standard_normal(len(th) - len(m.names))
    idx, dY = c.output_sensitivities(th, d)
    assert len(idx) and max(idx) < len(m.names)
    _assert_columns_are_differences(c, th, d, idx, dY)


def test_an_effect_that_shapes_the_output_has_no_exact_base_columns():
    """A static curve after the base (y = g(ŷ)) or a state-level effect changes how the
    output depends on the base's parameters: no exact columns are claimed for them."""
    from rigd.effects import REGISTRY
    from rigd.effects.compose import compose

    m = StateSpaceModel(["a"], ["y"], 100.0, 1, 0, 0, hold="zoh")
    m.set_record(500)
    rng = np.random.default_rng(6)
    d = IdData(rng.standard_normal((500, 1)), rng.standard_normal((500, 1)), 100.0, ["a"],
               ["y"])
    c = compose(m, [REGISTRY["static_nonlinearity"]])
    assert c.output_sensitivities(c.theta0(d), d) is None
