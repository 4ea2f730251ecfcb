"""Context.through_model, the model-filtered regressor of every input-site effect: exactly the
linear response for a linear model, and for a nonlinear one (a Duffing model after the cubic
step) independent of the size of the signal fed (units, rate: ``actuator_dynamics`` feeds
the input derivative, which scales with fs)."""

import benchmarks as B  # tests/diagnose/benchmarks.py
import numpy as np
import pytest

from rigd.effects import resolve
from rigd.effects._signals import derivative
from rigd.effects.context import Context, input_scale
from rigd.ident.iddata import from_record, replace_inputs
from rigd.ident.workflow import identify_record


@pytest.fixture(scope="module")
def duffing_models():
    """The Duffing record's data, its linear OE model and its model with cubic stiffness."""
    rec = B.duffing(seed=0, n=3000)
    data = from_record(rec, "generic")
    out = {}
    for key, effects in (("linear", []), ("cubic", resolve(["cubic_stiffness"]))):
        sub = identify_record(rec, "generic", method="oe", effects=effects,
                              order=2).submodels["generic"]
        out[key] = Context("generic", data, sub.structure, np.asarray(sub.theta, float),
                           np.zeros_like(data.outputs), slice(0, 2000), slice(2000, 3000))
    return data, out


def _fed_at_own_size(ctx, v):
    """The response to ``v`` as it is (no scaling), free response removed."""
    st, th, d = ctx.structure, ctx.theta, ctx.data
    full = np.asarray(st.simulate(th, replace_inputs(d, v.reshape(-1, 1))), float)
    zero = np.asarray(st.simulate(th, replace_inputs(d, np.zeros((d.n, 1)))), float)
    return full - zero


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_linear_model_response_unchanged_by_the_scaling(duffing_models):
    data, m = duffing_models
    ctx = m["linear"]
    v = derivative(ctx.u[:, 0], ctx.fs)  # ~ fs × the input: far from the input's size
    assert input_scale(ctx.u, v.reshape(-1, 1)) < 0.01
    got = ctx.through_model(v, 0)
    assert _rel(got, _fed_at_own_size(ctx, v)) < 1e-9
    assert _rel(ctx.through_model(1e3 * v, 0), 1e3 * got) < 1e-9


def test_cubic_model_response_independent_of_the_signal_size(duffing_models):
    data, m = duffing_models
    ctx = m["cubic"]
    assert "cubic_stiffness" in ctx.structure.effects
    v = derivative(ctx.u[:, 0], ctx.fs)
    got = ctx.through_model(v, 0)
    assert np.all(np.isfinite(got)) and np.any(got)
    # the model is nonlinear at these sizes: fed as it is, v and 1e3·v give responses that
    # are not 1e3 apart (what made actuator_dynamics depend on the rate given) ...
    raw = _fed_at_own_size(ctx, v)
    assert _rel(_fed_at_own_size(ctx, 1e-3 * v) * 1e3, raw) > 0.1
    # ... scaled to the record's input amplitude, the regressor is homogeneous in v
    assert _rel(ctx.through_model(1e3 * v, 0), 1e3 * got) < 1e-9
    assert _rel(ctx.through_model(1e-3 * v, 0), 1e-3 * got) < 1e-9
    # and fed at the input's own size it is the plain response (s = 1)
    assert _rel(ctx.through_model(ctx.u[:, 0], 0), _fed_at_own_size(ctx, ctx.u[:, 0])) < 1e-12


def test_input_scale_per_channel_not_mixing_units():
    rng = np.random.default_rng(0)
    u = rng.standard_normal((500, 2))
    v = 50.0 * rng.standard_normal((500, 2))
    s = input_scale(u, v)
    ratios = np.sqrt(np.mean(u ** 2, 0) / np.mean(v ** 2, 0))
    assert s == pytest.approx(ratios.min())  # no fed input above the record's amplitude
    # input 2 in mV (u and the signal replacing it × 1e3): the same scale
    assert input_scale(u * [1.0, 1e3], v * [1.0, 1e3]) == pytest.approx(s, rel=1e-12)
    # a column not fed (all zero) gives no ratio; an input that is identically zero neither
    v1 = v.copy()
    v1[:, 1] = 0.0
    assert input_scale(u, v1) == pytest.approx(ratios[0])
    u0 = u.copy()
    u0[:, 0] = 0.0
    assert input_scale(u0, v) == pytest.approx(ratios[1])
    assert input_scale(u, np.zeros_like(v)) == 1.0


def test_an_extension_that_cannot_be_simulated_on_the_model_gains_nothing_and_never_crashes():
    """The diagnosis once tried restoring-force hysteresis on a model with ``delay`` (its
    wrapper's kernel took the mechanical model only) during the forward selection on a
    friction stage and died with a ValueError. The composition (rigd.effects.compose) now
    carries it above the delay on the mechanical base (the Bouc–Wen force at zero gives the
    model without it); an extension that really cannot be simulated on the model still makes
    the refit report no gain, never a crash."""
    from rigd.diagnose.selection import refit_effect as _refit
    from rigd.effects import REGISTRY
    from rigd.effects.base import Effect

    rec = B.duffing(seed=0, n=3000)
    data = from_record(rec, "generic")
    # cubic_stiffness keeps the mechanical base (a restoring force needs [p, ṗ] states)
    sub = identify_record(rec, "generic", method="oe",
                          effects=resolve(["delay", "cubic_stiffness"]),
                          order=2).submodels["generic"]
    th = np.asarray(sub.theta, float)
    yhat = np.asarray(sub.structure.simulate(th, data), float)
    ctx = Context("generic", data, sub.structure, th, yhat, slice(0, 2000), slice(2000, 3000))
    eff = REGISTRY["hysteresis_restoring"]
    ext = eff.extend(sub.structure)
    y0 = ext.simulate(np.concatenate([th, np.zeros(4)]), data)   # a = 0: no Bouc–Wen force
    assert np.max(np.abs(y0 - yhat)) < 1e-3 * np.max(np.abs(yhat))  # RK4 vs exact hold

    class Unsimulable(Effect):
        name, sites = "unsimulable", ("input",)

        def param_names(self, base):
            return ["x"]

        def warm_start(self, ctx, sig):
            return np.zeros(1)

        def input_block(self, u, theta_e, data):
            raise ValueError("this model cannot carry it")

    r = _refit(Unsimulable(), ctx, None, data.slice(0, 2000), 50)
    assert np.array_equal(r.yhat, yhat)
