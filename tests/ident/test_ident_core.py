"""Core: bearing and actuator structures fitted by PEM/OE on simulated records with known
parameters, automatic initial guesses, uncertainties and physical read-outs."""

import numpy as np
import pytest
from ident_helpers import ACT_GAIN, ACT_POLES, B_TRUE, D_TRUE, K_TRUE, rotor_record

from rigd.ident.feedback import MechanicalFeedback
from rigd.ident.greybox.rotor import actuator_structure, bearing_structure
from rigd.ident.iddata import from_record
from rigd.ident.pem import fit, fit_percent
from rigd.ident.simulate import simulate_mechanical


@pytest.fixture(scope="module")
def rec():
    return rotor_record(n=15000, seed=1)


def _modes(S, theta):
    return S.readouts(theta)["modes"]


@pytest.mark.parametrize("method", ["pem", "oe"])
def test_bearing_known_parameters_from_automatic_start(rec, method):
    data = from_record(rec, "bearing")
    est, val = data.split()
    S = bearing_structure("foh")
    res = fit(S, est, method=method)  # no start values: automatic initial guess
    true = _modes(S, S.pack(K_TRUE, D_TRUE, B_TRUE))
    got = _modes(S, res.theta)
    for t, g in zip(true, got):
        assert abs(g["f_n_hz"] / t["f_n_hz"] - 1) < 0.005
        assert abs(g["zeta"] / t["zeta"] - 1) < 0.05
    ysim = S.simulate(res.theta, data)
    assert np.all(fit_percent(val.y, ysim[est.n:]) >= 95.0)
    G0 = np.array(S.readouts(res.theta)["static_gain"])
    np.testing.assert_allclose(G0, np.linalg.solve(K_TRUE, B_TRUE), rtol=0.02, atol=0.05)
    # uncertainties are finite, positive and the truth lies within a few of them for K
    Kf = res.theta[[S.names.index(n) for n in ("k_xx", "k_yy")]]
    sd = res.std[[S.names.index(n) for n in ("k_xx", "k_yy")]]
    assert np.all(sd > 0) and np.all(np.abs(Kf - np.diag(K_TRUE)) < 6 * sd + 1e-3 * Kf)


def test_automatic_initial_guess_is_close_but_refined(rec):
    data = from_record(rec, "bearing")
    S = bearing_structure("foh")
    th0 = S.theta0(data)
    m0 = _modes(S, th0)
    true = _modes(S, S.pack(K_TRUE, D_TRUE, B_TRUE))
    for t, g in zip(true, m0):
        assert abs(g["f_n_hz"] / t["f_n_hz"] - 1) < 0.05


def test_actuator_poles_and_gains(rec):
    data = from_record(rec, "actuator")
    est, val = data.split()
    S = actuator_structure()
    assert len(S.names) == 12
    res = fit(S, est)
    ro = res.readouts()["axes"]
    for ax in "xy":
        poles = sorted(ro[ax]["poles_rad_s"])
        for p, t in zip(poles, sorted(ACT_POLES[ax])):
            assert abs(p / t - 1) < 0.02, (ax, poles)
        assert abs(ro[ax]["gain"] / ACT_GAIN[ax] - 1) < 0.02
    assert np.all(fit_percent(val.y, S.simulate(res.theta, data)[est.n:]) >= 95.0)


def test_bearing_structure_has_paper_parameters():
    S = bearing_structure("foh")
    assert len(S.names) == 20
    assert {"k_xy", "d_yx", "b_xx", "bd_yy", "x0_4"} <= set(S.names)


def test_cubic_hook_matches_linear_when_k3_zero_and_differs_otherwise(rec):
    data = from_record(rec, "bearing").slice(0, 3000)
    lin = simulate_mechanical(K_TRUE, D_TRUE, B_TRUE, np.zeros(4), data.u, data.fs)
    rk = simulate_mechanical(K_TRUE, D_TRUE, B_TRUE, np.zeros(4), data.u, data.fs,
                             MechanicalFeedback(k3=np.array([1e-12, 0.0])), nsub=4)
    np.testing.assert_allclose(rk, lin, atol=2e-3 * np.abs(lin).max())
    hard = simulate_mechanical(K_TRUE, D_TRUE, B_TRUE, np.zeros(4), data.u, data.fs,
                               MechanicalFeedback(k3=np.array([K_TRUE[0, 0] * 0.05, 0.0])))
    assert np.abs(hard - lin).max() > 0.05 * np.abs(lin).max()
