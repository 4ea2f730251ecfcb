"""The linear design model of an extended structure (``Effect.linear``,
``Composed.linear_ss``, ``ModelFile.plant``): the effects with a small-signal linear
block (delay, actuator lags, an extra mode, a parallel lag, cross coupling) are in the
continuous G the H∞ design sees, composed as the structure's simulation composes them; the
others are left out with a reason. Checked against the structure's own simulation (the
fitted model, which knows nothing of python-control), not against the code under test."""

import control
import numpy as np
import pytest

from rigd.effects import extend, resolve
from rigd.ident.figures import fit_percent
from rigd.ident.greybox.rotor import actuator_structure, bearing_structure
from rigd.ident.iddata import IdData
from rigd.ident.modelfile import ModelFile, Submodel, load_model

FS = 5000.0


def _bearing_theta():
    """A two-mode bearing (≈ 110 / 125 Hz, ζ ≈ 0.04) with cross terms, Eq. 6 units; inputs
    linear between samples (FOH, as ``rigd identify`` fits the bearing)."""
    bs = bearing_structure("foh")
    w1, w2 = 2 * np.pi * 110.0, 2 * np.pi * 125.0
    K = np.array([[w1 ** 2, 0.04 * w1 * w2], [0.04 * w1 * w2, w2 ** 2]])
    D = np.array([[2 * 0.04 * w1, 5.0], [5.0, 2 * 0.04 * w2]])
    B = np.array([[4.0e5, 2.0e4], [-2.0e4, 4.2e5]])
    return bs, bs.pack(K, D, B)


def _data(n=6000, seed=3):
    """Smooth random inputs (band-limited to ≈ 600 Hz): the hold conventions of the
    simulation (linear interpolation, Tustin, exact lags) agree with the continuous model."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    u = np.zeros((n, 2))
    for j in range(2):
        for f in rng.uniform(5.0, 600.0, 40):
            u[:, j] += rng.normal() * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    return IdData(u, np.zeros((n, 2)), FS, ["u_x", "u_y"], ["e_x", "e_y"])


def _lsim(G, data):
    Gd = control.c2d(G, 1.0 / FS, "foh")
    return np.asarray(control.forced_response(Gd, U=data.u.T).outputs).T


EFFECT_THETA = {
    "delay": [2.3],                                              # samples
    "actuator_dynamics": [2.0e-4, 5.0e-5, 1.5e-4, 0.0],          # s (a zero lag allowed)
    "extra_mode": [330.0, 0.03, 0.4, 0.1, -0.05, 0.5, 0.2, 0.3, -0.1, 0.25],
    "extra_dynamics": [3.0e-3, 0.2, -0.1, 0.05, 0.3],
    "cross_coupling": [3.0e4, -2.0e4, 4.0, -3.0],
}


@pytest.mark.parametrize("names", [["delay"], ["actuator_dynamics"], ["extra_mode"],
                                   ["extra_dynamics"], ["cross_coupling"],
                                   ["delay", "extra_mode"],
                                   ["cross_coupling", "actuator_dynamics", "delay",
                                    "extra_mode"]])
def test_linear_block_matches_the_structures_simulation(names):
    bs, tb = _bearing_theta()
    st = extend(bs, names)
    theta = np.concatenate([tb] + [EFFECT_THETA[n] for n in st.effects])
    data = _data()
    y = st.simulate(theta, data)
    G, included, left_out = st.linear_ss(theta, FS)
    assert sorted(included) == sorted(names) and left_out == {}
    fit_with = np.mean(fit_percent(y, _lsim(G, data)))
    fit_base = np.mean(fit_percent(y, _lsim(bs.ss(tb), data)))
    assert fit_with > 98.5, (names, fit_with)   # the simulation: Tustin modes, interpolated delay
    # the effect matters here: the base alone is clearly further from the simulation
    assert 100 - fit_base > 3 * (100 - fit_with), (names, fit_base, fit_with)


def test_nonlinear_and_exogenous_effects_are_left_out_with_why():
    bs, tb = _bearing_theta()
    st = extend(bs, ["runout", "delay"])
    assert st.effects == ["delay", "runout"]           # input blocks inside output ones
    theta = np.concatenate([tb, [1.5], np.full(len(st.names) - len(tb) - 1, 0.3)])
    G, included, left_out = st.linear_ss(theta, FS)
    assert included == ["delay"] and set(left_out) == {"runout"}
    assert "shaft angle" in left_out["runout"]
    assert G.nstates > bs.ss(tb).nstates


def test_plant_of_a_model_file_carries_the_effects_and_survives_a_save(tmp_path):
    """``ModelFile.plant(effects=True)`` = G_bear·G_act with the effects' linear blocks
    (checked by hand); ``effects=False`` the base parts; the same after save/load;
    ``linear_effects`` names what is in and what is left out."""
    bs, tb = _bearing_theta()
    bst = extend(bs, ["delay", "extra_mode"])
    tbe = np.concatenate([tb, EFFECT_THETA["delay"], EFFECT_THETA["extra_mode"]])
    ast = actuator_structure()
    wa = 2 * np.pi * 500.0
    ta = ast.pack(np.diag([wa ** 2] * 2), np.diag([1.6 * wa] * 2), np.diag([2 * wa ** 2] * 2))
    hst = resolve(["hysteresis"])[0].extend(ast)
    tae = np.concatenate([ta, np.zeros(len(hst.names) - len(ta))])
    mf = ModelFile(FS, {"bearing": Submodel("bearing", bst, tbe, np.zeros_like(tbe)),
                        "actuator": Submodel("actuator", hst, tae, np.zeros_like(tae))})
    eff = mf.linear_effects()
    assert eff["bearing"] == {"included": ["delay", "extra_mode"], "left_out": {}}
    assert eff["actuator"]["included"] == [] and "hysteresis" in eff["actuator"]["left_out"]
    f = np.array([50.0, 130.0, 330.0, 600.0])
    s = 2j * np.pi * f
    base = np.array([mf.plant(effects=False)(x) for x in s])
    with_eff = np.array([mf.plant(effects=True)(x) for x in s])
    # by hand: G_bear(s)·e^{−s d/fs} + the parallel mode, times the actuator (the Padé of
    # order 6 for 2.3 samples is the exact delay to < 1e-3 up to 600 Hz)
    th = np.asarray(EFFECT_THETA["extra_mode"])
    w, z = 2 * np.pi * th[0], th[1]
    g, h = th[2:6].reshape(2, 2), th[6:10].reshape(2, 2)
    for x, got in zip(s, with_eff):
        mode = (g.T * w * w + h.T * w * x) / (x * x + 2 * z * w * x + w * w)
        want = (bs.ss(tb)(x) * np.exp(-x * 2.3 / FS) + mode) @ ast.ss(ta)(x)
        np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-6 * np.abs(want).max())
    assert not np.allclose(with_eff, base, rtol=0.02)
    # the actuator's hysteresis has no linear block: its G is the base part
    np.testing.assert_allclose([mf.ss("actuator", effects=True)(x) for x in s],
                               [mf.ss("actuator", effects=False)(x) for x in s], rtol=1e-12)
    mf.save(tmp_path / "m.yaml")
    back = load_model(tmp_path / "m.yaml", resolve)
    np.testing.assert_allclose([back.plant(effects=True)(x) for x in s], with_eff, rtol=1e-9)
