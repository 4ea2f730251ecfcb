"""rigd.ident.lti.references: the ARX and subspace references as candidates of choose_base
(independently simulated records of tests/gen)."""

from __future__ import annotations

import numpy as np

from rigd.ident.iddata import IdData
from rigd.ident.lti.arx import fit_arx
from rigd.ident.lti.order import reference_candidates
from rigd.ident.lti.references import arx_companion, reference_models
from tests.gen.linear import simulate_ct, structure, structure_2in_3modes, thermal
from tests.gen.record import add_noise
from tests.gen.signals import held_steps


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
    models = reference_models(d_est)
    assert [m[0] for m in models] == ["arx", "subspace"]
    cands = reference_candidates(d, d_est, est, val, models, "zoh", 4, 30)
    assert cands and all(c.family == "lti" for c in cands)
    assert {c.states for c in cands} <= {m[1].order for m in models}
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
    refs = reference_candidates(d, d_est, est, val, reference_models(d_est), "zoh", 0, 30)
    assert got >= max(r.fit_val for r in refs) - 1.0


def _process_3in_2out(seed: int, n: int = 2400):
    """A 3-input, 2-output process (kW, %, m³/h → bar, K at 0.5 Hz): a real pole of 40 s
    shared by both outputs, a second real pole of 12 s on the second, input 2 delayed by
    3 samples; inputs held steps."""
    rng = np.random.default_rng(seed)
    fs = 0.5
    A = np.diag([-1 / 40.0, -1 / 12.0])
    B = np.array([[0.02, -0.01, 0.015], [0.0, 0.06, -0.03]])
    C = np.array([[1.0, 0.0], [0.4, 1.0]])
    u = held_steps(n, rng, (8, 60), amp=3.0)
    u = np.column_stack([u[:, 0], held_steps(n, rng, (8, 60), amp=10.0)[:, 0] + 50.0,
                         held_steps(n, rng, (8, 60), amp=1.5)[:, 0] + 4.0])
    clean = simulate_ct(A, B, C, np.zeros((2, 3)), u - u.mean(0), fs, [0, 3, 0])
    y = add_noise(clean + np.array([2.0, 300.0]), 30.0, rng)
    return IdData(u, y, fs, ["heat", "valve", "flow"], ["pressure", "temp"])


def _two_modes(seed: int, n: int = 2400):
    """A lightly damped 2-mode structure (ζ 0.008 and 0.012 at 3.3 and 8.1 Hz, 50 Hz
    sampling), one shaker, two outputs."""
    g = structure([(3.3, 0.008), (8.1, 0.012)], n_inputs=1, n_outputs=2, fs=50.0, n=n,
                  seed=seed, snr_db=35.0)
    return IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))


def _reference_fit_est(lin, d, est, skip):
    """The reference's own fit on the estimation part: free run from its least-squares
    initial state (rigd's protocol), the first ``skip`` samples left out."""
    from rigd.ident.figures import fit_percent

    u, y = d.u[est], d.y[est]
    m = lin
    m.fit_x0(u, y, len(u))
    return float(np.mean(fit_percent(y[skip:], m.simulate(u)[skip:])))


def _carried_is_the_reference(d, hold):
    from rigd.ident.lti.candidates import settle
    from rigd.ident.lti.references import carried_candidates

    n = d.u.shape[0]
    est, val = slice(0, 2 * n // 3), slice(2 * n // 3, n)
    d_est = d.slice(est.start, est.stop)
    refs = reference_models(d_est)
    skip = max(settle(r[2]) + 1 for r in refs)
    cands = carried_candidates(d, d_est, est, val, refs, hold, skip, 120)
    assert len(cands) == len(refs)
    for (name, lin, _delays), c in zip(refs, cands):
        assert c.states == lin.order
        want = _reference_fit_est(lin, d, est, skip)
        # never worse than the reference it came from on the estimation data (with a
        # first-order hold the carried model is the reference to half a sample)
        assert c.fit_est >= want - (0.05 if hold == "zoh" else 1.0), (name, c.fit_est, want)


def test_a_carried_reference_fits_the_estimation_part_as_the_reference_does():
    """The ARX and subspace references carried into the modal family (B, C, D kept, x0 and
    offsets by least squares) fit the estimation part at least as well as the references
    themselves — a 3-input 2-output process with a delay and real poles, a lightly damped
    2-mode structure; zero- and first-order hold."""
    for d in (_process_3in_2out(3), _two_modes(5)):
        for hold in ("zoh", "foh"):
            _carried_is_the_reference(d, hold)


def test_choose_base_is_not_below_the_arx_on_held_out_data():
    """choose_base's base fits the held-out third at least as well as the plain ARX chosen
    on the estimation part (bench peers' protocol), to the admissibility margin MIN_GAIN, on
    records of other structures than the measured ones."""
    from bench.peers import _arx, _linear_peer
    from rigd.ident.figures import fit_percent
    from rigd.ident.lti.candidates import MIN_GAIN
    from rigd.ident.lti.order import choose_base

    for d in (_process_3in_2out(7), _two_modes(8)):
        n = d.u.shape[0]
        est, val = slice(0, 2 * n // 3), slice(2 * n // 3, n)
        c = choose_base(d, est, val, hold="foh")
        got = float(np.mean(fit_percent(d.y[val], c.structure.simulate(c.theta, d)[val])))
        arx = _linear_peer(_arx, d.u, d.y, est, val)["fit_percent"]
        assert got >= arx - MIN_GAIN, (d.output_names, got, arx)


def test_a_carried_reference_beyond_max_states_is_never_refined(monkeypatch):
    """A carried reference of more than MAX_STATES states competes as it is, even when its
    BIC ranks it among the scan's points to refine (018c616 refined the 60-state carried ARX
    of a 3-output record by output error there: over 10 CPU minutes); the scan's points and
    a small reference are refined as before, and the large one can still be chosen."""
    from types import SimpleNamespace

    import rigd.ident.lti.order as order
    from rigd.ident.lti.candidates import Candidate
    from rigd.ident.lti.statespace import StateSpaceModel

    def cand(states, bic, fit_val, delays=(0,)):
        m = StateSpaceModel(["u"], ["y"], 100.0, n_real=1, delays=list(delays))
        return Candidate("lti", states, m, np.zeros(1), bic, fit_val, fit_val, 10 * states)

    big = cand(order.MAX_STATES + 30, -900.0, 61.0)
    small_ref = cand(8, -800.0, 60.5, (1,))
    scan = [cand(k, -700.0 + k, 59.0) for k in (2, 3, 4, 5, 6)]
    refined = []

    def fake_refine(c, *args):
        refined.append(c)
        return c

    monkeypatch.setattr(order, "_refine", fake_refine)
    d_est = SimpleNamespace(input_names=["u"])
    choice = order._pick([big, small_ref, *scan], None, d_est, None, None, None,
                         [big, small_ref])
    assert all(c is not big for c in refined)
    assert any(c is small_ref for c in refined)
    assert sum(1 for c in refined if c in scan) == order.REFINED
    assert choice.states == big.states   # it competes: the best held-out fit, lowest BIC
