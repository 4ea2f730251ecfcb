"""Helpers for the simulated-plant tests (offered as fixtures: test folders have no __init__)."""

import numpy as np
import pytest

from rigd_drivers.sim.info import run_pd

FS = 5000.0
QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}


def _ar2_modes(records, fs):
    X = np.vstack([np.hstack([y[1:-1], y[:-2]]) for y in records])
    Y = np.vstack([y[2:] for y in records])
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)          # (4, 2): [A1ᵀ; A2ᵀ]
    A1, A2 = coef[:2].T, coef[2:].T
    comp = np.block([[A1, A2], [np.eye(2), np.zeros((2, 2))]])
    s = np.log(np.linalg.eigvals(comp).astype(complex)) * fs
    s = s[s.imag > 0]
    wn = np.abs(s)
    order = np.argsort(wn)
    return wn[order] / (2 * np.pi), (-s.real / wn)[order]


def modes_from_free_response(records, fs: float = FS, decimate: int = 4):
    """Natural frequencies (Hz) and damping ratios from 2-channel free responses.

    ``records``: list of (n, 2) arrays [e_x, e_y] after impacts, equilibrium removed.
    Start: least-squares vector AR(2) on the decimated records (exact for the noise-free
    4-state bearing); then a variable-projection least-squares fit of two damped sinusoids
    with shared poles to the full-rate records (robust to sensor noise).
    """
    from scipy.optimize import least_squares

    f0, z0 = _ar2_modes([r[::decimate] for r in records], fs / decimate)
    if f0.size != 2:
        f0 = np.array([f0[0], 1.07 * f0[0]]) if f0.size else np.array([100.0, 110.0])
        z0 = np.full(2, 0.05)

    def basis(theta, n):
        t = np.arange(n) / fs
        cols = []
        for f, z in ((theta[0], theta[1]), (theta[2], theta[3])):
            w = 2 * np.pi * f
            env = np.exp(-z * w * t)
            wd = w * np.sqrt(max(1 - z * z, 1e-9))
            cols += [env * np.cos(wd * t), env * np.sin(wd * t)]
        cols.append(np.ones(n))
        return np.column_stack(cols)

    def resid(theta):
        out = []
        for y in records:
            Phi = basis(theta, len(y))
            c, *_ = np.linalg.lstsq(Phi, y, rcond=None)
            out.append((y - Phi @ c).ravel())
        return np.concatenate(out)

    th0 = np.array([f0[0], z0[0], f0[1], z0[1]])
    sol = least_squares(resid, th0, x_scale=np.array([10, 0.01, 10, 0.01]))
    f = sol.x[[0, 2]]
    z = sol.x[[1, 3]]
    order = np.argsort(f)
    return f[order], z[order]


@pytest.fixture
def free_modes():
    return modes_from_free_response


@pytest.fixture
def pd():
    return run_pd


def run_reynolds_arrays(pa, drives, impact=None):
    """Run the physics-grade plant's batch kernel on ``analysis.make_arrays`` arrays ``pa``
    with ``drives`` (n, 4) V; ``impact`` (axis "x"|"y", peak N) starts a 1 ms hammer first.
    Returns the (n, N_IN) frames."""
    from rigd.frame import N_IN
    from rigd_drivers.reynolds import kernel as k
    from rigd_drivers.reynolds import layout as L

    frames = np.zeros((drives.shape[0], N_IN))
    if impact is not None:
        pa.params[L.H_IMP_AXIS] = 0.0 if impact[0] == "x" else 1.0
        pa.params[L.H_IMP_PEAK] = impact[1]
        pa.params[L.H_IMP_DUR] = 1e-3
        pa.params[L.H_IMP_SEQ] += 1
    k.run_batch(pa.state, pa.params, drives, frames)
    return frames


@pytest.fixture
def reynolds_run():
    return run_reynolds_arrays
