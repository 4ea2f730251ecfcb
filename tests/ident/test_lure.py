"""The state site of static_nonlinearity: a Lur'e block on the general LTI base
(rigd.effects.lure).

Checked against a simulation written out here with scipy's matrix exponential (not the
project's discretisation), on a base in real-block modal form with a delay and either hold;
F = 0 is the base exactly; the centres are never fitted; the site exists only where the base
carries it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from rigd.effects import REGISTRY
from rigd.effects.lure import simulate_lure, terms
from rigd.effects.static_nonlinearity import MAX_STATE_PARAMS
from rigd.ident.iddata import IdData
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import fit

SN = REGISTRY["static_nonlinearity"]
FS = 10.0


def _base(hold="zoh", delays=(2,)):
    m = StateSpaceModel(["u"], ["y1", "y2"], FS, n_complex=1, n_real=1, delays=list(delays),
                        hold=hold)
    lam = [complex(-0.6, 2.5), complex(-0.9, 0.0)]
    B = np.array([[0.8], [0.3], [0.5]])
    C = np.array([[1.0, 0.0, 1.0], [0.4, -0.2, 0.7]])
    x0 = np.array([0.1, 0.0, -0.05])
    th = m.pack(lam, B, C, x0=x0, yoff=np.array([2.0, -1.0]))
    return m, th


def _record(n=1500, seed=0):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // 25 + 1), 25)[:n, None] + 0.3
    return u


def _by_hand(m, th, F, cu, cy, u):
    """ZOH of x' = A x + B u_d + F φ(u_d, y), y = C x + y_off, written out (scipy expm)."""
    mats = m.matrices(th)
    A, B, C, yoff, x = mats["A"], mats["B"], mats["C"], mats["yoff"], mats["x0"].copy()
    nx, nt = A.shape[0], F.shape[1]
    M = np.zeros((nx + 1 + nt, nx + 1 + nt))
    M[:nx, :nx], M[:nx, nx:nx + 1], M[:nx, nx + 1:] = A, B, F
    E = expm(M / FS)
    Ad, Bd, Gf = E[:nx, :nx], E[:nx, nx:nx + 1], E[:nx, nx + 1:]
    d = m.delays[0]
    ud = np.concatenate([np.full(d, u[0, 0]), u[:, 0]])[:len(u)]
    y = np.empty((len(u), 2))
    for k in range(len(u)):
        y[k] = C @ x + yoff
        phi = [(ud[k] - cu[0]) ** 2, (ud[k] - cu[0]) ** 3]
        for i in range(2):
            phi += [(y[k, i] - cy[i]) ** 2, (y[k, i] - cy[i]) ** 3]
        x = Ad @ x + Bd[:, 0] * ud[k] + Gf @ np.array(phi)
    return y


def test_the_block_is_the_feedback_written_out():
    m, th = _base("zoh")
    u = _record()
    rng = np.random.default_rng(3)
    F = 0.05 * rng.standard_normal((m.nx, len(terms(1, 2, 3))))
    cu, cy = np.array([0.3]), np.array([2.1, -0.9])
    y = simulate_lure(m.linear_part(th), m.matrices(th)["x0"], m.matrices(th)["yoff"], F, cu,
                      cy, 3, u, FS)
    ref = _by_hand(m, th, F, cu, cy, u)
    assert np.all(np.isfinite(y))
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))
    lin = m.simulate(th, IdData(u, np.zeros((len(u), 2)), FS, ["u"], ["y1", "y2"]))
    assert np.max(np.abs(y - lin)) > 1e-3  # the feedback does something


@pytest.mark.parametrize("hold", ["zoh", "foh"])
def test_zero_feedback_is_the_base(hold):
    m, th = _base(hold)
    u = _record()
    d = IdData(u, np.zeros((len(u), 2)), FS, ["u"], ["y1", "y2"])
    ext = SN.extend(m)
    te = SN.theta0_effect(m, d)
    assert np.array_equal(ext.simulate(np.concatenate([th, te]), d), m.simulate(th, d))
    # F ≠ 0 goes through the Lur'e kernel with the base's own hold and delay
    nf = m.nx * len(terms(1, 2, 3))
    te2 = te.copy()
    te2[-nf:] = 1e-12
    y2 = ext.simulate(np.concatenate([th, te2]), d)
    assert np.max(np.abs(y2 - m.simulate(th, d))) <= 1e-9 * np.max(np.abs(y2))


def test_a_runaway_loop_is_a_failed_simulation_not_a_crash():
    m, th = _base()
    u = _record()
    F = np.zeros((m.nx, len(terms(1, 2, 3))))
    F[0, 3] = 50.0  # y1³ pushing state 0 the same way: explodes
    y = simulate_lure(m.linear_part(th), m.matrices(th)["x0"], m.matrices(th)["yoff"], F,
                      [0.0], [0.0, 0.0], 3, u, FS)
    assert np.isnan(y[-1]).all() and np.isfinite(y[0]).all()


def test_the_site_exists_where_the_base_carries_it():
    m, _ = _base()
    names = SN.param_names(m)
    nst = [n for n in names if n.startswith("sn_st")]
    assert len(nst) == m.nx * 3 * 2 and SN.fixed_names(m) == ["sn_cu_0", "sn_cy_0", "sn_cy_1"]
    big = StateSpaceModel(["u1", "u2"], ["y1", "y2"], FS, n_real=MAX_STATE_PARAMS // 8 + 1)
    assert not [n for n in SN.param_names(big) if n.startswith("sn_st")]
    from rigd.ident.greybox.mechanical import generic_structure

    mech = generic_structure(["u"], ["y"])
    assert not [n for n in SN.param_names(mech) if n.startswith(("sn_st", "sn_c"))]


def test_the_fit_recovers_a_feedback_and_keeps_the_centres():
    m, th = _base("zoh", delays=(0,))
    u = _record(2000, seed=5)
    F = np.zeros((m.nx, len(terms(1, 2, 3))))
    F[2, 2], F[0, 4] = -0.4, 0.3  # y1² into the real pole, y2² into the pair
    cu, cy = np.array([0.3]), np.array([2.0, -1.0])
    mats = m.matrices(th)
    y = simulate_lure(m.linear_part(th), mats["x0"], mats["yoff"], F, cu, cy, 3, u, FS)
    d = IdData(u, y, FS, ["u"], ["y1", "y2"])
    ext = SN.extend(m)
    ext.bind_record(d)
    te = SN.theta0_effect(m, d)
    fixed = [n for n in ext.names if n.startswith(("sn_in", "sn_out"))]
    res = fit(ext, d, method="oe", theta0=np.concatenate([th, te]), fixed=fixed)
    k = len(th)
    centres = [ext.names.index(n) for n in SN.fixed_names(m)]
    assert np.array_equal(res.theta[centres], np.concatenate([th, te])[centres])
    yh = ext.simulate(res.theta, d)
    lin = fit(m, d, method="oe", theta0=th)
    e_lin = np.linalg.norm(y - m.simulate(lin.theta, d))
    assert np.linalg.norm(y - yh) < 0.05 * e_lin  # the block takes what no linear fit can
    assert res.theta[k:].shape == te.shape


def test_identify_with_the_curve_round_trips_through_the_model_file(tmp_path):
    """``rigd identify --add static_nonlinearity`` on a general LTI base fits the state site
    too; the model file rebuilds the same model (compare from the file = compare of the
    in-memory model), the centres stored beside F."""
    from rigd import api
    from tests.gen import nonlinear as NL

    rec = NL.state_dependent_lag(seed=3, n=1500).record()
    path = tmp_path / "m.yaml"
    ident = api.identify(rec, add="static_nonlinearity", out=path, yardstick=False)
    params = ident.parameters
    assert any(n.startswith("sn_st") for n in params), sorted(params)
    assert {"sn_cu_0", "sn_cy_0"} <= set(params)
    from_file = api.compare(path, rec, part="validation", yardstick=False)
    in_memory = api.compare(ident, rec, part="validation", yardstick=False)
    fit = float(np.mean(from_file.summary()["fit_percent"]))
    assert fit == float(np.mean(in_memory.summary()["fit_percent"]))
    # identify's own figure (its initial state handled on the whole record) is within a hair
    assert abs(fit - float(np.mean(ident.fit_percent))) < 0.1
    plain = api.identify(rec, yardstick=False)
    assert fit > float(np.mean(plain.fit_percent)) + 5.0  # the curve is worth its place
