"""identify and diagnose on a record that is not a rotor's: one base, chosen by
rigd.ident.lti.order.choose_base on the estimation part (issue 20, items 1-4)."""

from __future__ import annotations

import numpy as np

from rigd.diagnose.diagnosis import diagnose_record
from rigd.ident.lti.modal import gains_by_least_squares
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import fit, fit_percent
from rigd.ident.workflow import identify_record
from tests.gen.linear import THREE_MODES, structure_2in_3modes


def test_two_input_three_mode_record_identify_and_diagnose_share_the_base():
    g = structure_2in_3modes(seed=3, n=4000)
    rec = g.record()
    mf = identify_record(rec, "generic", method="oe")
    sub = mf.submodels["generic"]
    order = sub.fit_percent["order"]
    assert order["family"] == "lti" and order["modes"] == 3, order
    got = sorted(sub.structure.resonances_hz(sub.theta))
    assert np.allclose(got, [f for f, _ in THREE_MODES], rtol=0.02), got
    # within 1 point of the true-order model (three pairs from the truth's poles, OE)
    from rigd.ident.iddata import from_record

    d = from_record(rec, "generic")
    k = int(round(2 * d.n / 3))
    true = StateSpaceModel(d.input_names, d.output_names, d.fs, n_complex=3,
                           hold=sub.structure.hold)
    true.set_record(k)
    lam = [complex(p) for p in g.truth["poles"] if complex(p).imag > 0]
    d_est = d.slice(0, k)
    th = fit(true, d_est, method="oe",
             theta0=gains_by_least_squares(true, lam, d_est)).theta
    f_true = float(np.mean(fit_percent(d.y[k:], true.simulate(th, d)[k:])))
    f_got = sub.fit_percent["validation_mean"]
    assert f_got >= f_true - 1.0, (f_got, f_true)
    # diagnose's base model is identify's model: the same family, order, delays, numbers
    dg = diagnose_record(rec, refit=False, yardstick=False)
    part = dg.parts[0]
    assert part.order["family"] == "lti" and part.order["states"] == order["states"]
    assert part.order["delays_samples"] == order["delays_samples"]
    assert np.allclose(part.steps[0].theta, sub.theta)
    assert abs(part.fit_percent - f_got) < 1e-6
