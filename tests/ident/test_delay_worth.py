"""What a base's input delays are worth (rigd.ident.lti.delay_worth): a transport delay costs
many held-out fit points when the base is refitted without it; a delay that only stands in
for a lag of the dynamics (two lags in series, no delay) costs less than MIN_FIT_GAIN.
Records simulated outside rigd (tests/gen/linear.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rigd.ident.iddata import IdData
from rigd.ident.lti.delay_worth import delay_worth
from rigd.ident.lti.process import ProcessModel
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import fit
from rigd.ident.thresholds import MIN_FIT_GAIN
from tests.gen.linear import simulate_ct
from tests.gen.record import add_noise
from tests.gen.signals import held_steps

N, FS = 1500, 1.0
EST, VAL = slice(0, 1000), slice(1000, N)


def _record(A, B, delay: float, seed: int) -> IdData:
    rng = np.random.default_rng(seed)
    u = 50.0 + held_steps(N, rng, (3, 20), amp=45.0)
    y = simulate_ct(A, B, [[0.0] * (len(A) - 1) + [1.0]], [[0.0]], u - 50.0, FS, [delay])
    return IdData(u, add_noise(y, 35.0, rng), FS, ["u"], ["y"])


def _fitted(kind: str, d: IdData, delays):
    m = ProcessModel(["u"], ["y"], FS, kind, delays, "zoh")
    d_est = d.slice(EST.start, EST.stop)
    m.set_record(d_est.n)
    return m, fit(m, d_est, method="oe", theta0=m.theta0(d_est), skip=max(delays)).theta


@pytest.mark.parametrize("seed", [0, 1])
def test_a_transport_delay_is_worth_many_points(seed):
    d = _record([[-1 / 5.0]], [[0.6 / 5.0]], 3.0, seed)       # τ 5 s, 3 s delay
    m, th = _fitted("P1D", d, [3])
    assert delay_worth(m, th, d, EST, VAL) >= 10 * MIN_FIT_GAIN


@pytest.mark.parametrize("seed", [0, 1])
def test_a_delay_standing_in_for_two_lags_is_not_paid(seed):
    """Two lags in series (τ 6 s and 4 s), no delay: a P2D given a 2-sample delay fits
    about as well as one without."""
    A = [[-1 / 6.0, 0.0], [1 / 4.0, -1 / 4.0]]
    d = _record(A, [[0.6 / 6.0], [0.0]], 0.0, seed)
    m, th = _fitted("P2D", d, [2])
    assert delay_worth(m, th, d, EST, VAL) < MIN_FIT_GAIN


def test_no_delay_no_worth():
    d = _record([[-1 / 5.0]], [[0.6 / 5.0]], 0.0, 0)
    m, th = _fitted("P1D", d, [0])
    assert delay_worth(m, th, d, EST, VAL) is None
    lti = StateSpaceModel(["u"], ["y"], FS, n_real=1, delays=[0], hold="zoh")
    assert delay_worth(lti, np.zeros(len(lti.names)), d, EST, VAL) is None
