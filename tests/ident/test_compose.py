"""The one composition mechanism (rigd.effects.compose): input blocks → base → output blocks,
a Lur'e feedback block for state-level effects.

Where the maths is the same, the composed model simulates what the nested wrappers
(rigd.effects.base.ExtendedStructure) simulated, to round-off: each effect alone, several in
the order forward selection adds them (not sorted by site), on a mechanical base and on the
general LTI base; names, bounds, start values, read-outs and the linear design model agree;
an effect the base cannot carry is refused with the reason.
"""

import numpy as np
import pytest

from rigd.effects import REGISTRY
from rigd.effects.base import ExtendedStructure, is_mechanical
from rigd.effects.compose import Composed, carries, compose
from rigd.effects.restoring_hysteresis import RestoringExtended
from rigd.effects.runout import HARMONICS
from rigd.ident.iddata import IdData
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.mechanical import generic_structure

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


def _old(structure, names):
    for nm in names:
        wrapper = RestoringExtended if nm == "hysteresis_restoring" else ExtendedStructure
        structure = wrapper(structure, REGISTRY[nm])
    return structure


def _assert_same(old, new, th, data):
    assert new.names == old.names
    assert new.effects == old.effects
    y_old = np.asarray(old.simulate(th, data))
    y_new = new.simulate(th, data)
    assert np.all(np.isfinite(y_old))
    scale = float(np.max(np.abs(y_old)))
    assert np.max(np.abs(y_new - y_old)) <= 1e-9 * scale


@pytest.mark.parametrize("name", sorted(REGISTRY))
@pytest.mark.parametrize("dims", [(1, 1), (2, 2)])
def test_each_effect_alone_simulates_as_the_wrapper(name, dims):
    nu, ny = dims
    if name == "cross_coupling" and ny == 1:
        pytest.skip("cross coupling needs two axes")
    data = _record(nu, ny)
    base, tb = _mechanical(nu, ny)
    th = np.r_[tb, _theta_e(name, nu, ny)]
    new = compose(base, [REGISTRY[name]])
    _assert_same(_old(base, [name]), new, th, data)
    # the effect changes the output (the comparison is not of two base models)
    assert np.max(np.abs(new.simulate(th, data) - base.simulate(tb, data))) > 1e-3


@pytest.mark.parametrize("order", [
    ["cubic_stiffness", "delay", "static_nonlinearity", "extra_dynamics"],   # sorted by site
    ["extra_dynamics", "static_nonlinearity", "cubic_stiffness", "delay"],   # as selected
    ["static_nonlinearity", "delay", "extra_dynamics"],
])
def test_several_effects_compose_in_the_wrappers_order(order):
    nu, ny = 2, 2
    data = _record(nu, ny, seed=1)
    base, tb = _mechanical(nu, ny)
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    new = compose(base, [REGISTRY[nm] for nm in order])
    _assert_same(_old(base, order), new, th, data)
    # one effect more, added to a composed model, stays one flat model
    grown = compose(base, [REGISTRY[order[0]]])
    for nm in order[1:]:
        grown = compose(grown, [REGISTRY[nm]])
    assert isinstance(grown, Composed) and grown.base is base
    assert np.max(np.abs(grown.simulate(th, data) - new.simulate(th, data))) == 0.0


@pytest.mark.parametrize("order", [
    ["cubic_stiffness", "hysteresis_restoring"],
    ["hysteresis_restoring", "delay", "extra_mode"],
    ["cross_coupling", "hysteresis_restoring", "static_nonlinearity"],
])
def test_the_restoring_force_composes_as_its_wrapper(order):
    nu, ny = 2, 2
    data = _record(nu, ny, seed=5)
    base, tb = _mechanical(nu, ny)
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    _assert_same(_old(base, order), compose(base, [REGISTRY[nm] for nm in order]), th, data)


def test_input_and_output_effects_on_the_lti_base():
    nu, ny = 2, 1
    data = _record(nu, ny, seed=2)
    base, tb = _lti(nu, ny)
    order = ["delay", "static_nonlinearity", "extra_dynamics"]
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    _assert_same(_old(base, order), compose(base, [REGISTRY[nm] for nm in order]), th, data)


def test_parameters_bounds_readouts_and_linear_model_as_the_wrapper():
    nu, ny = 2, 2
    data = _record(nu, ny, seed=4)
    base, tb = _mechanical(nu, ny)
    order = ["delay", "cubic_stiffness", "extra_dynamics", "static_nonlinearity"]
    th = np.concatenate([tb] + [_theta_e(nm, nu, ny) for nm in order])
    old, new = _old(base, order), compose(base, [REGISTRY[nm] for nm in order])
    np.testing.assert_array_equal(new.theta0(data), old.theta0(data))
    for a, b in zip(new.bounds(), old.bounds()):      # record-free bounds
        np.testing.assert_array_equal(a, b)
    old.bind_record(data)
    new.bind_record(data)
    for a, b in zip(new.bounds(), old.bounds()):      # relative to the record
        np.testing.assert_array_equal(a, b)
    assert new.readouts(th).keys() == old.readouts(th).keys()
    assert new.spec() == old.spec()
    G_old, inc_old, left_old = old.linear_ss(th, FS)
    G_new, inc_new, left_new = new.linear_ss(th, FS)
    assert inc_new == inc_old and left_new == left_old
    np.testing.assert_allclose(G_new.A, G_old.A, rtol=0, atol=0)


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
    saved = _old(base, order)
    path = ModelFile(FS, {"generic": Submodel("generic", saved, th, np.zeros(th.size))}).save(
        tmp_path / "m.yaml")
    sm = load_model(path, resolve_effects=resolve).submodels["generic"]
    assert isinstance(sm.structure, Composed) and sm.structure.effects == order
    assert sm.structure.names == saved.names
    y0 = np.asarray(saved.simulate(th, data))
    assert np.max(np.abs(sm.structure.simulate(sm.theta, data) - y0)) <= 1e-9 * np.max(
        np.abs(y0))
