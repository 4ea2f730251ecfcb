"""Fixed-order multi-model H∞ tuning (rigd.design.structured) on the simulated plant's truth:
the parametrisation's guarantees, the σ̄ kernel, stability over the design set and over 100
fresh operating points, the refusal of a structure that cannot work, no numerical warnings."""

import warnings

import numpy as np
import pytest
from design_helpers import truth_model_file

from rigd.cli import main
from rigd.design import discretize, pipeline, robustness, structured
from rigd.design.fixed_order import FixedOrder
from rigd.design.structured_design import design_set, problem
from rigd.design.weights import load_design_config
from rigd.errors import InputError
from rigd_drivers.sim import truth as simtruth

CFG = "config/design.yaml"


@pytest.fixture(scope="module")
def tuned():
    """The shipped config's structured design, every warning an error (the demo path)."""
    cfg = load_design_config(CFG)
    G = simtruth.plant_s(4000.0, 7.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res, _ = pipeline.design(G, cfg, plant_at=simtruth.plant_s, compare=False)
    return cfg, G, res


@pytest.mark.parametrize("n,m", [(3, 2), (4, 2), (5, 2), (6, 2), (4, 1), (4, 0)])
def test_structure_is_stable_with_exact_dc_zeros_for_any_parameters(n, m):
    fo = FixedOrder(n, m)
    rng = np.random.default_rng(n * 10 + m)
    for _ in range(20):
        x = rng.normal(0, 1.5, fo.n_params)
        A, B, C, D = fo.matrices(x)
        assert np.all(np.linalg.eigvals(A).real < 0)
        # K(s) = D − Σ sᵏ C A^{-(k+1)} B: the first m coefficients vanish
        coef = [D - C @ np.linalg.solve(A, B)] + [
            C @ np.linalg.matrix_power(np.linalg.inv(A), k + 1) @ B for k in range(1, m)]
        for c in coef[:m]:
            assert np.abs(c).max() <= 1e-9 * max(1.0, np.abs(C).max() * np.abs(B).max())
        if m:
            assert np.abs(C).max() > 1e-6        # not the trivial zero controller
        s = 1j * np.array([0.3, 1.0, 4.0])
        K = fo.ss(x)
        ref = robustness.freq_response(K, s.imag * structured.OMEGA_SCALE / (2 * np.pi))
        assert np.allclose(fo.response(x, s), ref, rtol=1e-9, atol=1e-12)


def test_weighted_sigma_kernel_equals_svd_of_the_closed_loop():
    cfg = load_design_config(CFG)
    G = simtruth.plant_s(4000.0, 7.0)
    f = np.array([5.0, 80.0, 140.0, 300.0, 1200.0])
    fo = FixedOrder(4, 2)
    prob = problem([("a", G), ("b", simtruth.plant_s(0.0, 3.0))], cfg, fo, f)
    x = structured.random_start(fo, np.random.default_rng(3))
    sig = prob.sigma(x)
    Kz = discretize.tustin(fo.ss(x), cfg.fs_hz, cfg.discretization.prewarp_hz)
    K = robustness.freq_response(Kz, f)
    for i, m in enumerate(prob.models):
        S = np.linalg.inv(np.eye(2)[None] + m.Gf @ K)
        X = np.concatenate([prob.Wp[:, None, None] * S, -prob.Wu[:, None, None] * (K @ S)], 1)
        Y = np.concatenate([np.broadcast_to(np.eye(2), S.shape), cfg.weights.W_d * m.Gf], 2)
        assert np.allclose(sig[i], np.linalg.svd(X @ Y, compute_uv=False)[:, 0], rtol=1e-9)


def test_structured_controller_is_order_4_with_zeros_at_dc(tuned):
    cfg, G, res = tuned
    assert res.method == "structured" and res.order == 4 and res.K_z.nstates == 4
    Kz1 = robustness.freq_response(res.K_z, np.array([0.0]))[0]
    assert np.abs(Kz1).max() < 1e-9                      # K(z = 1) = 0
    assert res.lowfreq_gain_ratio < 0.02


def test_stable_at_every_model_of_the_design_set(tuned):
    cfg, G, res = tuned
    models = design_set(G, cfg, simtruth.plant_s)
    assert len(models) == len(res.design_set) >= 5 + cfg.structured.n_samples - 1
    for lab, Gi in models:
        assert robustness.is_stable(discretize.zoh(Gi, cfg.fs_hz), res.K_z), lab
    assert all(r["stable"] and r["rho"] < 1 for r in res.design_set)


def test_stable_at_100_fresh_operating_points_of_the_true_plant(tuned):
    cfg, G, res = tuned
    pts = robustness.random_operating_points(100, 20261123, cfg.robustness.omega_rpm,
                                             cfg.robustness.p_inj_bar)
    bad = [(om, p) for om, p in pts if not robustness.is_stable(simtruth.plant_z(om, p), res.K_z)]
    assert not bad


def test_beats_balanced_truncation_of_the_same_order(tuned):
    """Balanced truncation of the full-order controller to the same 4 states either fails to
    stabilise the design set or has a larger worst-case γ on it than the tuned K."""
    from rigd.design import reduce
    from rigd.design.structured_design import gamma_on_set

    cfg, G, res = tuned
    Kbt = discretize.tustin(reduce.reduce_controller(res.K_full, 4), cfg.fs_hz,
                            cfg.discretization.prewarp_hz)
    stable = all(robustness.is_stable(discretize.zoh(Gi, cfg.fs_hz), Kbt)
                 for _lab, Gi in design_set(G, cfg, simtruth.plant_s))
    if stable:
        assert res.gamma < max(r["gamma"] for r in gamma_on_set(G, cfg, Kbt, simtruth.plant_s))


def test_order_that_cannot_hold_the_structure_is_refused():
    cfg = load_design_config(CFG)
    with pytest.raises(InputError, match="cannot hold 2 zeros at DC"):
        pipeline.design(simtruth.plant_s(4000.0, 7.0), cfg, order=2, compare=False)


def test_cli_refuses_such_an_order_with_one_line(tmp_path, capsys):
    model = truth_model_file(tmp_path / "G_p.yaml")
    out = tmp_path / "c.yaml"
    rc = main(["design", "--model", str(model), "-o", str(out), "--order", "2",
               "--method", "structured"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "--order 2" in err
    assert not out.exists()


def test_unstabilisable_set_is_refused():
    """A set no controller of the structure can stabilise (an open-loop unstable model whose
    instability sits at DC, where K has its zeros): refused, one line."""
    import control

    cfg = load_design_config(CFG)
    G = simtruth.plant_s(4000.0, 7.0)
    f = np.array([50.0, 100.0, 200.0])
    unstable = control.ss(np.diag([30.0, 30.0]), np.eye(2), np.eye(2), np.zeros((2, 2)))
    prob = problem([("design", G), ("unstable", unstable)], cfg, FixedOrder(4, 2), f)
    x0 = structured.random_start(prob.structure, np.random.default_rng(0))
    with pytest.raises(InputError) as e:
        structured.tune(prob, [x0], screen_iters=2, polish=((30.0, 2),))
    assert "stabilises not all 2 models" in str(e.value) and "\n" not in str(e.value)
