"""A refit with effects on a large base holds the base (rigd.ident.pipeline.held_base,
MAX_REFIT_FREE): only the effects' parameters and the output offsets move; on a small base
everything moves as before."""

from __future__ import annotations

import numpy as np

from rigd.effects import REGISTRY
from rigd.ident.figures import fit_percent
from rigd.ident.iddata import IdData
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import free_mask
from rigd.ident.pipeline import MAX_REFIT_FREE, held_base, refit_with

FS = 10.0


def model(nr: int, delays=(0, 0, 0)) -> StateSpaceModel:
    m = StateSpaceModel(["u1", "u2", "u3"], ["y1", "y2", "y3"], FS, n_real=nr, hold="zoh",
                        delays=list(delays))
    m.set_record(800)
    return m


def true_theta(m: StateSpaceModel, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lam = -2 * np.pi * FS * np.geomspace(2e-3, 0.2, m.nr)   # real poles, 1/s
    B = rng.standard_normal((m.nx, 3)) * np.abs(lam)[:, None] * 0.3
    C = rng.standard_normal((3, m.nx))
    C[0] = 1.0  # the normalised row (norm_rows 0)
    return m.pack(lam, B, C, yoff=np.array([1.0, -2.0, 0.5]))


def test_held_only_above_the_limit():
    small, large = model(10), model(50)
    assert held_base(small, "oe") == []
    free_large = int(free_mask(large, None, "oe").sum())
    assert free_large > MAX_REFIT_FREE
    held = held_base(large, "oe")
    assert len(held) == free_large - 3 and not any(n.startswith("yoff_") for n in held)
    # what is fixed already does not count: holding enough brings it under the limit
    assert held_base(large, "oe", held[:free_large - MAX_REFIT_FREE]) == []


def test_delay_refitted_on_a_held_large_base():
    """A 50-state, 3-input plant whose inputs are delayed by 2 samples; the base is the
    same plant without the delay, at its true parameters, output offsets wrong. The refit
    (started at 1.5 samples, as a signature scan would start it) holds the base's
    parameters, moves the offsets and the delay, and recovers the fit."""
    truth = model(50, delays=(2, 2, 2))
    th = true_theta(truth)
    rng = np.random.default_rng(1)
    u = rng.standard_normal((800, 3))
    y = truth.simulate(th, IdData(u, np.zeros((800, 3)), FS, truth.input_names,
                                  truth.output_names))
    data = IdData(u, y, FS, truth.input_names, truth.output_names)
    base = model(50)
    th_base = th.copy()
    off = base.offset_index
    th_base[off] = 0.0  # offsets to be refitted
    fp0 = float(np.mean(fit_percent(y, base.simulate(th_base, data))))
    ext, res, _, kept = refit_with(base, th_base, [REGISTRY["delay"]], data, "oe",
                                   starts=[np.array([1.5])])
    assert res is not None and res.info["held_base"] == len(held_base(base, "oe"))
    assert kept == tuple(held_base(base, "oe"))  # what a later refit of the step keeps
    nb = len(base.names)
    keep = np.ones(nb, bool)
    keep[off] = False
    assert np.array_equal(res.theta[:nb][keep], th_base[keep])      # the base held
    assert np.allclose(res.theta[off], [1.0, -2.0, 0.5], atol=0.05)  # the offsets moved
    fp = float(np.mean(fit_percent(y, ext.simulate(res.theta, data))))
    assert abs(res.theta[nb] - 2.0) < 0.05
    assert fp > fp0 + 10 and fp > 99
