"""rigd.ident.lti.references: the ARX and subspace references as candidates of choose_base
(independently simulated records of tests/gen)."""

from __future__ import annotations

import numpy as np

from rigd.ident.iddata import IdData
from rigd.ident.lti.arx import fit_arx
from rigd.ident.lti.order import reference_candidates
from rigd.ident.lti.references import arx_companion, reference_models
from tests.gen.linear import structure_2in_3modes, thermal


def test_arx_companion_has_the_arx_models_poles():
    g = structure_2in_3modes(seed=4, n=2000, n_outputs=2)
    m = fit_arx(g.u, g.y, 4, 4, 1)
    want = np.sort_complex(np.linalg.eigvals(m.to_linear().A))
    got = np.sort_complex(np.linalg.eigvals(arx_companion(m.a)))
    assert got.shape == (8,) and np.allclose(got, want, atol=1e-9)


def test_reference_candidates_reach_the_arx_held_out_fit():
    """Each reference becomes a general LTI model of the reference's order and delays whose
    held-out fit (free run on from the estimation part) is within a point of the plain ARX's
    own — before any output-error refit."""
    from bench.peers import _arx, _linear_peer

    g = thermal(delay=3.0, tau_s=30.0, n=1800, seed=11)
    d = IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))
    est, val = slice(0, 1200), slice(1200, 1800)
    d_est = d.slice(0, 1200)
    models = reference_models(d_est, "zoh")
    assert [m[0] for m in models] == ["arx", "subspace"]
    cands = reference_candidates(d, d_est, est, val, models, "zoh", 4, 30)
    assert cands and all(c.family == "lti" for c in cands)
    assert {c.states for c in cands} <= {m[1].shape[0] for m in models}
    arx = _linear_peer(_arx, d.u, d.y, est, val)["fit_percent"]
    assert max(c.fit_val for c in cands) >= arx - 1.0


def test_choose_base_is_not_below_the_references():
    """The base chosen with the references competing fits the held-out part within a point of
    the plain ARX's and the subspace model's own held-out fits (bench peers' protocol) and of
    the best reference-derived candidate."""
    from bench.peers import _arx, _linear_peer, _subspace
    from rigd.ident.figures import fit_percent
    from rigd.ident.lti.order import choose_base

    g = structure_2in_3modes(seed=6, n=2400)
    d = IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))
    est, val = slice(0, 1600), slice(1600, 2400)
    c = choose_base(d, est, val, hold="zoh")
    got = float(np.mean(fit_percent(d.y[val], c.structure.simulate(c.theta, d)[val])))
    for peer in (_arx, _subspace):
        assert got >= _linear_peer(peer, d.u, d.y, est, val)["fit_percent"] - 1.0
    d_est = d.slice(0, 1600)
    refs = reference_candidates(d, d_est, est, val, reference_models(d_est, "zoh"), "zoh",
                                0, 30)
    assert got >= max(r.fit_val for r in refs) - 1.0
