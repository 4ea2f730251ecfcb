"""The output-error base of a generic record is the base choice's model, not refitted
(rigd.ident.pipeline._generic_base, rigd.ident.pem.evaluate): the held-out check of
rigd.ident.lti.order.choose_base chose those parameters, and a second fit to convergence would
move them where the check did not look."""

import numpy as np

from rigd.ident.iddata import IdData
from rigd.ident.pem import evaluate, fit
from rigd.ident.pipeline import FitSettings, fit_base
from tests.gen import linear


def test_output_error_base_is_the_base_choice_as_chosen():
    rec = linear.thermal(delay=2, tau_s=25.0, fs=2.0, n=2400, seed=3).record()
    bf = fit_base(rec, "generic", FitSettings(method="oe"))
    assert bf.order.family != "mechanical"
    np.testing.assert_array_equal(bf.theta, bf.order.theta)
    assert bf.result.method == "oe" and bf.result.status.startswith("kept")
    assert np.all(np.isfinite(bf.result.std))
    # PEM is still a fit of its own (the base choice's parameters are output-error ones)
    bp = fit_base(rec, "generic", FitSettings(method="pem"))
    assert not np.array_equal(bp.theta, bp.order.theta)


def test_evaluate_reports_what_a_converged_fit_reports():
    """At an output-error optimum, evaluate's cost, fit and standard deviations are the
    fit's own (its Jacobian is taken at the same point)."""
    g = linear.thermal(delay=0, tau_s=8.0, fs=1.0, n=1500, seed=5)
    rec = g.record()
    data = IdData(rec.col(g.inputs[0])[:, None], rec.col(g.outputs[0])[:, None], rec.fs,
                  list(g.inputs), list(g.outputs))
    from rigd.ident.lti.order import choose_base

    ch = choose_base(data, slice(0, 1000), slice(1000, 1500), order=1, hold="zoh")
    d_est = data.slice(0, 1000)
    res = fit(ch.structure, d_est, method="oe", theta0=ch.theta, ftol=1e-10)
    ev = evaluate(ch.structure, d_est, res.theta)
    np.testing.assert_allclose(ev.theta, res.theta)
    np.testing.assert_allclose(ev.cost, res.cost, rtol=1e-6)
    np.testing.assert_allclose(ev.fit_percent, res.fit_percent, atol=1e-9)
    free = res.std > 0
    assert free.any()
    np.testing.assert_allclose(ev.std[free], res.std[free], rtol=0.05)
    # away from the optimum the cost is larger: evaluate does not move the parameters
    th = res.theta.copy()
    th[free] *= 1.2
    assert evaluate(ch.structure, d_est, th).cost > 1.5 * res.cost
