"""The design model conditioned for H∞ synthesis (rigd.design.condition): poles far above the
loop rate residualised, non-minimal states removed, a change that matters refused."""

import numpy as np
import pytest
from design_helpers import parallel_mode

from rigd.design.condition import condition
from rigd.design.robustness import freq_response
from rigd.effects._linear import lag_block, series_inputs
from rigd.errors import InputError
from rigd_drivers.sim import truth as simtruth

FS = 5000.0


@pytest.fixture(scope="module")
def plant():
    return simtruth.plant_s(4000.0, 7.0)


def test_fast_lag_is_residualised_and_the_response_below_nyquist_kept(plant):
    G = series_inputs(plant, [lag_block([1e-6, 2e-6])] * 2)     # poles at 80 and 160 kHz
    Gc, info = condition(G, FS)
    assert info["states"] == [plant.nstates + 4, plant.nstates]
    assert len(info["fast_poles_hz"]) == 4 and min(info["fast_poles_hz"]) > FS
    for f, tol in ((np.linspace(70.0, 190.0, 25), 0.005), (np.linspace(10.0, FS / 2, 50), 0.06)):
        R = freq_response(plant, f)        # the lags' phase: 0.004 rad at 190 Hz, 0.05 at fs/2
        num = np.linalg.svd(freq_response(Gc, f) - R, compute_uv=False)[:, 0]
        assert np.max(num / np.linalg.svd(R, compute_uv=False)[:, 0]) < tol
    assert np.all(np.asarray(Gc.D) == 0)


def test_slow_dynamics_are_kept_and_unreachable_ones_removed(plant):
    G = series_inputs(plant, [lag_block([1e-3])] * 2)            # a 160 Hz lag: kept
    Gc, info = condition(G, FS)
    assert all(np.array_equal(getattr(Gc, k), getattr(G, k)) for k in "ABC")
    assert info["fast_poles_hz"] == [] and info["removed_nonminimal"] == 0
    Gc, info = condition(parallel_mode(plant, 150.0, 0.05, 0.0), FS)     # a mode nobody sees
    assert info["removed_nonminimal"] == 4 and Gc.nstates == plant.nstates
    assert info["change"] < 1e-3        # minreal's new realization: ≈ 5e-4


def test_fast_dynamics_that_matter_are_refused(plant):
    with pytest.raises(InputError) as e:       # an 8 kHz mode carrying the whole DC gain
        condition(parallel_mode(plant, 8000.0, 0.05, 1.0), FS)
    assert "500 Hz" in e.value.message and "8e+03" in e.value.message
