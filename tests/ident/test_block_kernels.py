"""Block-by-block discretisation and simulation of a real-block modal model
(rigd.ident.block_kernels), against scipy.signal's discretisation and simulation (an oracle
independent of rigd's dense and block paths), and the dense path where the block path does
not apply."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sig

from rigd.ident import block_kernels as BK
from rigd.ident.model import LinearPart
from rigd.ident.simulate import predict_linear, simulate_linear


def modal(nc, nr, ni, nu, ny, fs, seed=0, bscale=1.0):
    """A random stable real-block modal model: nc pairs, nr real poles (up to 2 fs),
    ni integrators; B in units ``bscale``."""
    rng = np.random.default_rng(seed)
    nx = 2 * nc + nr + ni
    A, s = np.zeros((nx, nx)), 0
    for _ in range(nc):
        wn, z = 2 * np.pi * fs * rng.uniform(1e-3, 0.4), rng.uniform(0.01, 0.9)
        A[s:s + 2, s:s + 2] = [[-z * wn, wn * np.sqrt(1 - z * z)],
                               [-wn * np.sqrt(1 - z * z), -z * wn]]
        s += 2
    for _ in range(nr):
        A[s, s] = -2 * np.pi * fs * rng.uniform(1e-4, 2.0)
        s += 1
    B = rng.standard_normal((nx, nu)) * bscale
    C = rng.standard_normal((ny, nx))
    return A, B, C, rng


def reference(A, B, C, u, fs, hold):
    """ZOH: scipy.signal's cont2discrete and dlsim; FOH: rigd's dense Van Loan path
    (rigd.lti.foh), from rest."""
    ny, nu = C.shape[0], B.shape[1]
    if hold == "zoh":
        sysd = sig.cont2discrete((A, B, C, np.zeros((ny, nu))), 1 / fs, "zoh")
        return sig.dlsim((*sysd[:4], 1 / fs), u)[1]
    from rigd.ident.sim_kernels import lsim_kernel
    from rigd.ident.simulate import _discrete

    Ad, Bd, ue = _discrete(A, B, 1 / fs, "foh", u)
    y = np.empty((u.shape[0], ny))
    lsim_kernel(Ad, Bd, C, np.zeros(A.shape[0]), ue, y)
    return y


@pytest.mark.parametrize("hold", ["zoh", "foh"])
@pytest.mark.parametrize("shape", [(1, 1, 1, 1, 1), (3, 2, 0, 2, 2), (40, 10, 2, 3, 6)])
def test_block_simulation_equals_scipy(hold, shape):
    nc, nr, ni, nu, ny = shape
    fs = 50.0
    A, B, C, rng = modal(nc, nr, ni, nu, ny, fs, bscale=1e4)
    n = 600
    u = rng.standard_normal((n, nu))
    lp = LinearPart(A, B, C, np.zeros((ny, nu)), None, (0,) * nu, hold)
    assert BK.blocks(A) is not None  # the block path runs
    y = simulate_linear(lp, np.zeros(A.shape[0]), u, fs)
    ref = reference(A, B, C, u, fs, hold)
    scale = np.max(np.abs(ref))
    assert np.max(np.abs(y - ref)) <= 1e-9 * scale


def test_block_discretisation_equals_scipy_zoh_with_tiny_and_huge_units():
    """Ad and Bd per block equal scipy's ZOH of the whole model, for B in 1e-8 and 1e8
    units (the units enter after the exponential)."""
    fs = 1000.0
    for bscale in (1e-8, 1e8):
        A, B, C, _ = modal(5, 3, 1, 2, 1, fs, seed=3, bscale=bscale)
        bs, nb = BK.blocks(A)
        Ad, Bd, _ = BK.discrete(A, B, 1 / fs, "zoh", bs, nb, np.zeros((3, 2)))
        Ad0, Bd0, *_ = sig.cont2discrete((A, B, C, np.zeros((1, 2))), 1 / fs, "zoh")
        assert np.max(np.abs(Ad - Ad0)) < 1e-12
        assert np.max(np.abs(Bd - Bd0)) < 1e-10 * np.max(np.abs(Bd0))


def test_blocks_found_and_refused():
    A, *_ = modal(2, 2, 1, 1, 1, 10.0)
    bs, nb = BK.blocks(A)
    assert nb == 5 and list(bs[:nb + 1]) == [0, 2, 4, 5, 6, 7]
    # a mechanical [p, ṗ] model is not block-diagonal in 2×2 blocks: the dense path
    K = np.diag([4.0, 9.0])
    K[0, 1] = K[1, 0] = 1.0
    mech = np.block([[np.zeros((2, 2)), np.eye(2)], [-K, -0.1 * np.eye(2)]])
    assert BK.blocks(mech) is None
    # three coupled states
    A3 = np.array([[-1.0, 1.0, 0.0], [0.0, -2.0, 1.0], [0.0, 0.0, -3.0]])
    assert BK.blocks(A3) is None
    assert BK.blocks(np.diag([-1.0, -2.0])) is None  # two states: the dense path


def test_non_finite_gives_nan_not_an_exception():
    A, B, C, rng = modal(3, 1, 0, 1, 1, 10.0)
    B[2, 0] = np.nan
    lp = LinearPart(A, B, C, np.zeros((1, 1)), None, (0,), "zoh")
    y = simulate_linear(lp, np.zeros(A.shape[0]), rng.standard_normal((50, 1)), 10.0)
    assert y.shape == (50, 1) and np.all(np.isnan(y[1:]))


def test_block_predictor_equals_the_innovation_form_written_out():
    """x̂[k+1] = Ad x̂ + Bd u + K (y − C x̂) with scipy's Ad, Bd, stepped in numpy."""
    fs = 20.0
    A, B, C, rng = modal(4, 2, 0, 2, 2, fs, seed=5)  # no integrator: |λ| < 1 strictly
    nx, n = A.shape[0], 300
    K = 0.01 * rng.standard_normal((nx, 2))
    u, ym = rng.standard_normal((n, 2)), rng.standard_normal((n, 2))
    lp = LinearPart(A, B, C, np.zeros((2, 2)), K, (0, 0), "zoh")
    x0 = rng.standard_normal(nx)
    yh = predict_linear(lp, x0, u, ym, fs)
    Ad, Bd, *_ = sig.cont2discrete((A, B, C, np.zeros((2, 2))), 1 / fs, "zoh")
    x, ref = x0.copy(), np.empty((n, 2))
    for k in range(n):
        ref[k] = C @ x
        x = Ad @ x + Bd @ u[k] + K @ (ym[k] - ref[k])
    assert yh is not None
    assert np.max(np.abs(yh - ref)) <= 1e-9 * np.max(np.abs(ref))
