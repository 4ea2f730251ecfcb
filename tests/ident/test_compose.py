"""The one composition mechanism (rigd.effects.compose): input blocks → base → output blocks,
a Lur'e feedback block for state-level effects.

The composed model is checked against the same model written out by hand from the base's own
simulator (a delayed input, the polynomials, a first-order lag path, the cubic force in the
mechanical simulator), and against the nesting order of the wrappers it replaced (input blocks
from the last-added effect to the first, output blocks from the first to the last, the state
feedback of all in the base): commit 6de47f3 compared all thirteen effects with those
wrappers to 1e-9. Names, bounds and start values come flat from the base and each effect; a
model file reads back into the same model; an effect the base cannot carry is refused with
the reason.
"""

import numpy as np
import pytest

from rigd.effects import REGISTRY
from rigd.effects._signals import lag1, shift
from rigd.effects.base import is_mechanical
from rigd.effects.compose import Composed, carries, compose
from rigd.effects.runout import HARMONICS
from rigd.ident.feedback import MechanicalFeedback
from rigd.ident.greybox.mechanical import generic_structure
from rigd.ident.iddata import IdData, replace_inputs
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.simulate import simulate_mechanical

FS = 200.0
N = 600


def _record(nu: int, ny: int, seed: int = 0) -> IdData:
    rng = np.random.default_rng(seed)
    u = np.cumsum(rng.standard_normal((N, nu)), axis=0) * 0.05
    u += 0.4 * np.sign(np.sin(np.arange(N)[:, None] / (7.0 + np.arange(nu))))
    y = rng.standard_normal((N, ny))  # outputs only set the effects' start values here
    phi = np.mod(2 * np.pi * 1.7 * np.arange(N) / FS, 2 * np.pi)   # a turning shaft
    return IdData(u, y, FS, [f"u{j + 1}" for j in range(nu)],
                  [f"y{i + 1}" for i in range(ny)], aux={"phi": phi})


def _mechanical(nu: int, ny: int):
    st = generic_structure([f"u{j + 1}" for j in range(nu)], [f"y{i + 1}" for i in range(ny)],
                           hold="foh")
    w = 2 * np.pi * np.array([3.0, 5.5][:ny])
    K = np.diag(w ** 2) + 0.1 * w[0] ** 2 * (1 - np.eye(ny))
    D = np.diag(2 * 0.08 * w)
    B = np.outer(w ** 2, np.linspace(1.0, 0.6, nu))[:ny]
    th = st.pack(K, D, B, x0=np.r_[0.05 * np.ones(ny), np.zeros(ny)])
    th[st.offset_index] = 0.1
    return st, th


def _lti(nu: int, ny: int):
    st = StateSpaceModel([f"u{j + 1}" for j in range(nu)], [f"y{i + 1}" for i in range(ny)],
                         FS, n_complex=1, n_real=1, hold="foh")
    lam = [complex(-2.0, 2 * np.pi * 4.0), complex(-6.0, 0.0)]
    rng = np.random.default_rng(3)
    B = rng.standard_normal((st.nx, nu)) * 20
    C = rng.standard_normal((ny, st.nx))
    th = st.pack(lam, B, C, x0=0.01 * np.ones(st.nx), yoff=0.2 * np.ones(ny))
    return st, th


#: effect parameters at a size that changes the output visibly (per effect, given nu, ny)
def _theta_e(name: str, nu: int, ny: int) -> np.ndarray:
    if name == "delay":
        return np.array([2.6])
    if name == "static_nonlinearity":
        return np.r_[np.tile([0.3, -0.2], nu), np.tile([0.05, 0.02], ny)]
    if name == "extra_dynamics":
        return np.r_[0.08, np.linspace(0.5, -0.3, nu * ny)]
    if name == "cubic_stiffness":
        k = 400.0 * np.ones(ny)
        return np.r_[k, 0.5 * k] if ny > 1 else k
    if name == "actuator_dynamics":
        return np.tile([0.02, 0.01], nu)
    if name == "creep":
        return np.r_[np.full(2 * nu, 0.1), np.full(2 * nu, 0.05), 0.1, 1.0]
    if name == "hysteresis":
        return np.r_[np.full(nu, 0.2), 2.0]
    if name == "extra_mode":
        return np.r_[12.0, 0.05, np.full(nu * ny, 0.3), np.full(nu * ny, 0.1)]
    if name == "integrator":
        return np.r_[np.full(nu * ny, 0.5), np.full(nu, 0.1)]
    if name == "runout":
        return np.linspace(0.05, 0.2, 2 * len(HARMONICS) * ny)
    if name == "cross_coupling":
        return np.r_[np.full(ny * (ny - 1), 30.0), np.full(ny * (ny - 1), 0.5)]
    if name == "friction":
        return np.r_[np.full(ny, 50.0), np.full(ny, 0.5)]
    if name == "hysteresis_restoring":
        return np.r_[np.full(ny, 30.0), np.full(ny, 2.0), np.full(ny, 0.5), np.full(ny, 0.3)]
    raise KeyError(name)


def _by_hand(base, tb, names, th_e, data):
    """The composition written out: input blocks from the last-added effect to the first,
    the base with the summed feedback (or the one state model of its own, where the effect
    has one on this base), output blocks
    from the first to the last, each seeing the inputs its own input side received."""
    effects = [REGISTRY[nm] for nm in names]
    seen, d = [], data
    for e in reversed(effects):
        seen.append(d)
        if "input" in e.sites:
            d = replace_inputs(d, e.input_block(np.asarray(d.inputs, float), th_e[e.name], d))
    seen.reverse()
    fb, own = None, None
    for e in effects:
        if "state" in e.sites:
            if callable(getattr(e, "state_simulate", None)) and e.owns_state(base):
                own = e
            blk = e.state_block(th_e[e.name], data)
            if blk is not None:
                fb = blk if fb is None else fb.plus(blk)
    if own is not None:
        y = own.state_simulate(base, tb, th_e[own.name], fb, d)
    elif fb is None:
        y = base.simulate(tb, d)
    else:
        y = base.simulate(tb, d, fb)
    for e, de in zip(effects, seen):
        if "output" in e.sites:
            y = e.output_block(np.asarray(y, float), th_e[e.name], de)
    return np.asarray(y, float)


def _close(a, b):
    assert np.all(np.isfinite(b))
    assert np.max(np.abs(np.asarray(a) - b)) <= 1e-9 * float(np.max(np.abs(b)))


@pytest.mark.parametrize("dims", [(1, 1), (2, 2)])
def test_four_effects_are_the_model_written_out(dims):
    """delay, static_nonlinearity, extra_dynamics and cubic_stiffness, each alone, against
    the formula from the base's own simulator."""
    nu, ny = dims
    data = _record(nu, ny)
    base, tb = _mechanical(nu, ny)
    u = np.asarray(data.inputs, float)

    def run(name, th_e):
        return compose(base, [REGISTRY[name]]).simulate(np.r_[tb, th_e], data)

    th_e = _theta_e("delay", nu, ny)
    ud = np.column_stack([shift(u[:, j], th_e[0]) for j in range(nu)])
    _close(run("delay", th_e), base.simulate(tb, replace_inputs(data, ud)))

    th_e = _theta_e("static_nonlinearity", nu, ny)
    a, c = th_e[:2 * nu].reshape(nu, 2), th_e[2 * nu:].reshape(ny, 2)
    y = base.simulate(tb, replace_inputs(data, u + a[:, 0] * u ** 2 + a[:, 1] * u ** 3))
    _close(run("static_nonlinearity", th_e), y + c[:, 0] * y ** 2 + c[:, 1] * y ** 3)

    th_e = _theta_e("extra_dynamics", nu, ny)
    lags = np.column_stack([lag1(u[:, j], th_e[0], FS) for j in range(nu)])
    _close(run("extra_dynamics", th_e),
           base.simulate(tb, data) + lags @ th_e[1:].reshape(nu, ny))

    th_e = _theta_e("cubic_stiffness", nu, ny)
    K, D, B, _, x0 = base.unpack(tb)
    p = simulate_mechanical(K, D, B, x0, u, FS, hold="foh", feedback=MechanicalFeedback(
        k3=th_e[:ny], k3_cross=th_e[ny:] if ny > 1 else None))
    _close(run("cubic_stiffness", th_e), p + base.output_offset(tb))
    # each changes the output (the comparison is not of two base models)
    assert np.max(np.abs(run("cubic_stiffness", th_e) - base.simulate(tb, data))) > 1e-3


@pytest.mark.parametrize("name", sorted(REGISTRY))
@pytest.mark.parametrize("dims", [(1, 1), (2, 2)])
def test_each_effect_alone_is_its_blocks_around_the_base(name, dims):
    nu, ny = dims
    if name == "cross_coupling" and ny == 1:
        pytest.skip("cross coupling needs two axes")
    if "mode" in REGISTRY[name].requires:
        pytest.skip("a mode effect needs a modal base: tests/diagnose/test_mode_site.py")
    data = _record(nu, ny)
    base, tb = _mechanical(nu, ny)
    th_e = _theta_e(name, nu, ny)
    new = compose(base, [REGISTRY[name]])
    assert new.names == list(base.names) + REGISTRY[name].param_names(base)
    y = new.simulate(np.r_[tb, th_e], data)
    _close(y, _by_hand(base, tb, [name], {name: th_e}, data))
    # the effect changes the output (the comparison is not of two base models)
    assert np.max(np.abs(y - base.simulate(tb, data))) > 1e-3


def _params(order, nu, ny):
    return {nm: _theta_e(nm, nu, ny) for nm in order}


@pytest.mark.parametrize("order", [
    ["cubic_stiffness", "delay", "static_nonlinearity", "extra_dynamics"],   # sorted by site
    ["extra_dynamics", "static_nonlinearity", "cubic_stiffness", "delay"],   # as selected
    ["static_nonlinearity", "delay", "extra_dynamics"],
])
def test_several_effects_compose_in_the_wrappers_order(order):
    nu, ny = 2, 2
    data = _record(nu, ny, seed=1)
    base, tb = _mechanical(nu, ny)
    th_e = _params(order, nu, ny)
    th = np.concatenate([tb] + [th_e[nm] for nm in order])
    new = compose(base, [REGISTRY[nm] for nm in order])
    _close(new.simulate(th, data), _by_hand(base, tb, order, th_e, data))
    # one effect more, added to a composed model, stays one flat model
    grown = REGISTRY[order[0]].extend(base)
    for nm in order[1:]:
        grown = REGISTRY[nm].extend(grown)
    assert isinstance(grown, Composed) and grown.base is base and grown.effects == order
    assert np.max(np.abs(grown.simulate(th, data) - new.simulate(th, data))) == 0.0


def test_the_order_of_input_blocks_is_the_order_added():
    """delay then the input curve: the curve acts on the raw input, then it is delayed (the
    last-added input block is the first the input meets)."""
    nu, ny = 1, 1
    data = _record(nu, ny, seed=7)
    base, tb = _mechanical(nu, ny)
    d, sn = _theta_e("delay", nu, ny), _theta_e("static_nonlinearity", nu, ny)
    y1 = compose(base, [REGISTRY["delay"], REGISTRY["static_nonlinearity"]]).simulate(
        np.r_[tb, d, sn], data)
    y2 = compose(base, [REGISTRY["static_nonlinearity"], REGISTRY["delay"]]).simulate(
        np.r_[tb, sn, d], data)
    u = np.asarray(data.inputs, float)[:, 0]
    curve = u + sn[0] * u ** 2 + sn[1] * u ** 3
    y = base.simulate(tb, replace_inputs(data, shift(curve, d[0])[:, None]))
    _close(y1, y + sn[2] * y ** 2 + sn[3] * y ** 3)
    assert np.max(np.abs(y1 - y2)) > 1e-6 * np.max(np.abs(y1))


def _composed_equals_written_out(base_of, nu, ny, seed, order):
    data = _record(nu, ny, seed=seed)
    base, tb = base_of(nu, ny)
    th_e = _params(order, nu, ny)
    sn = REGISTRY["static_nonlinearity"]
    if "static_nonlinearity" in order and sn.state_carried(base):
        # the state site on a general LTI base: centres at the record's means, a small F
        k = len(sn.param_names(base)) - th_e["static_nonlinearity"].size
        rest = np.r_[np.mean(data.inputs, axis=0), np.mean(data.outputs, axis=0)]
        f = 1e-3 * np.cos(np.arange(k - rest.size))
        th_e["static_nonlinearity"] = np.r_[th_e["static_nonlinearity"], rest, f]
    th = np.concatenate([tb] + [th_e[nm] for nm in order])
    _close(compose(base, [REGISTRY[nm] for nm in order]).simulate(th, data),
           _by_hand(base, tb, order, th_e, data))


@pytest.mark.parametrize("order", [
    ["cubic_stiffness", "hysteresis_restoring"],
    ["hysteresis_restoring", "delay", "extra_mode"],
    ["cross_coupling", "hysteresis_restoring", "static_nonlinearity"],
])
def test_the_restoring_force_composes_with_the_others(order):
    _composed_equals_written_out(_mechanical, 2, 2, 5, order)


def test_input_and_output_effects_on_the_lti_base():
    _composed_equals_written_out(_lti, 2, 1, 2, ["delay", "static_nonlinearity",
                                                 "extra_dynamics"])


def test_the_restoring_force_at_zero_size_is_the_base_with_the_same_cubic_terms():
    # the Bouc–Wen kernel's own integration of the cubic and cross-axis cubic stiffness
    # against the mechanical base's simulator given the same feedback (a = 0: no loop)
    nu, ny = 2, 2
    data = _record(nu, ny, seed=6)
    base, tb = _mechanical(nu, ny)
    cub = REGISTRY["cubic_stiffness"]
    fb = cub.state_block(_theta_e("cubic_stiffness", nu, ny), data)
    assert np.any(fb.k3_cross != 0)
    te = _theta_e("hysteresis_restoring", nu, ny)
    te[:ny] = 0.0
    y = REGISTRY["hysteresis_restoring"].state_simulate(base, tb, te, fb, data)
    ref = base.simulate(tb, data, fb)
    assert np.max(np.abs(y - ref)) <= 1e-6 * float(np.max(np.abs(ref)))
    y_lin = REGISTRY["hysteresis_restoring"].state_simulate(base, tb, te, None, data)
    assert np.max(np.abs(y_lin - ref)) > 1e-3 * float(np.max(np.abs(ref)))


def test_the_restoring_force_refuses_dry_friction_beside_it():
    nu, ny = 1, 1
    data = _record(nu, ny, seed=7)
    base, tb = _mechanical(nu, ny)
    order = ["friction", "hysteresis_restoring"]
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    with pytest.raises(ValueError, match="cannot be simulated beside friction"):
        compose(base, [REGISTRY[nm] for nm in order])
    with_friction = compose(base, [REGISTRY["friction"]])
    assert "beside friction" in REGISTRY["hysteresis_restoring"].not_offered(with_friction)
    # the kernel refuses it too, were the two ever handed to it together
    fb = REGISTRY["friction"].state_block(_theta_e("friction", nu, ny), data)
    with pytest.raises(ValueError, match="dry friction"):
        REGISTRY["hysteresis_restoring"].state_simulate(
            base, tb, th[-4 * ny:], fb, data)


def test_an_effect_enters_a_model_once():
    base, _ = _mechanical(1, 1)
    once = compose(base, [REGISTRY["delay"]])
    with pytest.raises(ValueError, match="delay added twice"):
        once.with_effect(REGISTRY["delay"])
    assert REGISTRY["delay"].not_offered(once) == "delay is already in the model"
    assert REGISTRY["extra_dynamics"].not_offered(once) is None


def test_parameters_bounds_readouts_and_linear_model_come_flat_from_the_parts():
    from rigd.effects.scales import RecordScale

    nu, ny = 2, 2
    data = _record(nu, ny, seed=4)
    base, tb = _mechanical(nu, ny)
    order = ["delay", "cubic_stiffness", "extra_dynamics", "static_nonlinearity"]
    effects = [REGISTRY[nm] for nm in order]
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    new = compose(base, effects)
    assert new.names == list(base.names) + [n for e in effects for n in e.param_names(base)]
    np.testing.assert_array_equal(new.theta0(data), np.concatenate(
        [base.theta0(data)] + [e.theta0_effect(base, data) for e in effects]))
    lo, hi = base.bounds()
    for k, b in enumerate(new.bounds()):              # record-free bounds
        np.testing.assert_array_equal(b, np.concatenate(
            [(lo, hi)[k]] + [e.param_bounds(base)[k] for e in effects]))
    new.bind_record(data)
    rec = RecordScale.of(data)
    for k, b in enumerate(new.bounds()):              # relative to the record
        np.testing.assert_array_equal(b, np.concatenate(
            [(lo, hi)[k]] + [e.record_bounds(base, rec)[k] for e in effects]))
    out = new.readouts(th)
    assert all(out[n] == v for n, v in zip(new.names[new.nb:], th[new.nb:]))
    assert new.spec() == dict(base.spec(), effects=order)
    G, included, left_out = new.linear_ss(th, FS)
    assert included == ["delay", "extra_dynamics"]
    assert set(left_out) == {"cubic_stiffness", "static_nonlinearity"}
    G_hand = base.ss(tb)
    for nm in included:
        G_hand = REGISTRY[nm].linear(G_hand, _theta_e(nm, nu, ny), base, FS)
    np.testing.assert_array_equal(G.A, G_hand.A)


def test_a_state_level_effect_is_refused_by_a_base_without_mechanical_states():
    base, _ = _lti(1, 1)
    assert "mechanical" not in carries(base)
    with pytest.raises(ValueError, match="positions and velocities of a mechanical model"):
        compose(base, [REGISTRY["cubic_stiffness"]])
    mech, _ = _mechanical(1, 1)
    composed = compose(mech, [REGISTRY["delay"]])
    assert "mechanical" in carries(composed) and is_mechanical(composed)
    assert not is_mechanical(compose(base, [REGISTRY["delay"]]))


@pytest.mark.parametrize("order", [["delay", "cubic_stiffness", "extra_dynamics"],
                                   ["hysteresis_restoring", "static_nonlinearity", "runout"]])
def test_a_model_file_with_effects_reads_back_into_the_same_model(tmp_path, order):
    """Effects are stored by name and parameters by name: the file rebuilds the composition
    (the order of the effects kept), which simulates what was saved."""
    from rigd.effects import resolve
    from rigd.ident.modelfile import ModelFile, Submodel, load_model

    nu, ny = 2, 2
    data = _record(nu, ny, seed=6)
    base, tb = _mechanical(nu, ny)
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    saved = compose(base, [REGISTRY[nm] for nm in order])
    path = ModelFile(FS, {"generic": Submodel("generic", saved, th, np.zeros(th.size))}).save(
        tmp_path / "m.yaml")
    sm = load_model(path, resolve_effects=resolve).submodels["generic"]
    assert isinstance(sm.structure, Composed) and sm.structure.effects == order
    assert sm.structure.names == saved.names
    y0 = np.asarray(saved.simulate(th, data))
    assert np.max(np.abs(sm.structure.simulate(sm.theta, data) - y0)) <= 1e-9 * np.max(
        np.abs(y0))


def test_the_predictor_of_the_mechanical_base_with_parallel_modes_adds_what_it_simulates():
    """With no disturbance gain (B_d = 0) the one-step predictor is the simulation: output
    offsets and the parallel modes (with their free response) are taken off the measurement
    and added back, the state-level feedback enters both alike."""
    from rigd.ident.feedback import MechanicalFeedback

    nu, ny = 2, 2
    data = _record(nu, ny, seed=8)
    base, tb = _mechanical(nu, ny)
    st = base.with_modes(1)
    th = st.theta0(data)
    th[:st.nb] = tb
    th[st.nb:st.nb + 2] = [9.0, 0.05]                      # the mode: 9 Hz, ζ 0.05
    th[st.nb + 2:st.nb + 2 + nu * ny] = [0.4, -0.2, 0.1, 0.3]
    th[st.nb + 2 + nu * ny:] = [0.02, -0.01, 0.0, 0.01]    # its free response
    fb = MechanicalFeedback(k3=np.array([300.0, 200.0]))
    for feedback in (None, fb):
        y = st.simulate(th, data, feedback)
        assert np.max(np.abs(y - base.simulate(tb, data, feedback))) > 1e-3   # modes count
        yhat = st.predict(th, IdData(data.u, y + 0.3, FS, data.input_names,
                                     data.output_names), feedback)
        _close(yhat, y)


def test_a_model_file_naming_an_effect_its_base_cannot_carry_is_refused(tmp_path):
    """A general LTI base naming cubic_stiffness (a hand-edited file): one line naming the
    file and why, not a traceback."""
    from rigd.effects import resolve
    from rigd.errors import InputError
    from rigd.ident.modelfile import ModelFile, Submodel, load_model

    base, tb = _lti(1, 1)
    path = ModelFile(FS, {"generic": Submodel("generic", base, tb, np.zeros(tb.size))}).save(
        tmp_path / "m.yaml")
    text = path.read_text().replace("effects: []", "effects: [cubic_stiffness]")
    assert "cubic_stiffness" in text
    path.write_text(text)
    with pytest.raises(InputError, match="positions and velocities") as exc:
        load_model(path, resolve_effects=resolve)
    assert "m.yaml" in str(exc.value)


def test_static_nonlinearity_of_degree_five_is_the_polynomial_written_out():
    """A curve of another degree (powers 2 … 5 per input and per output, its own per
    output on a 2 × 2 record) is the polynomial written out, in the parameters' order."""
    import copy

    nu, ny = 2, 2
    data = _record(nu, ny)
    base, tb = _mechanical(nu, ny)
    u = np.asarray(data.inputs, float)
    eff = copy.copy(REGISTRY["static_nonlinearity"])
    eff.degree = 5
    names = eff.param_names(base)
    assert len(names) == 4 * (nu + ny) and names[:4] == [f"sn_in{k}_0" for k in (2, 3, 4, 5)]
    a = np.array([[0.3, -0.2, 0.05, 0.01], [-0.1, 0.1, 0.02, -0.01]])
    c = np.array([[0.05, 0.02, -0.01, 0.002], [0.0, 0.03, 0.0, -0.004]])
    y = base.simulate(tb, replace_inputs(data, u + sum(a[:, k] * u ** (k + 2)
                                                       for k in range(4))))
    _close(compose(base, [eff]).simulate(np.r_[tb, a.ravel(), c.ravel()], data),
           y + sum(c[:, k] * y ** (k + 2) for k in range(4)))
