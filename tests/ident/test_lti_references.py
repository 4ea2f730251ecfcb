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
