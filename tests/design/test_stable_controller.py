"""Design models with a lightly damped right-half-plane zero pair (a structural mode in
parallel with the bearing, as the improved model's extra mode): the full-order H∞ controller
is made stable by itself (relaxed γ), the truncation route then finds an order, and the
robustness figures measure the reduction at the resonances of the damping band only."""

import numpy as np
import pytest
from design_helpers import parallel_mode

from rigd.design import hinf, pipeline, robustness
from rigd.design.weights import load_design_config, three_level
from rigd_drivers.sim import truth as simtruth

CFG = "config/design.yaml"


@pytest.fixture(scope="module")
def cfg():
    return load_design_config(CFG)


@pytest.fixture(scope="module")
def plant():
    return simtruth.plant_s(4000.0, 7.0)


def _rhp_zeros_hz(G):
    z = np.asarray(G.zeros(), complex)
    return z[(z.real > 0) & (np.abs(z) < 2 * np.pi * 1000.0)] / (2 * np.pi)


def _max_re(A):
    return float(np.max(np.linalg.eigvals(np.asarray(A, float)).real))


def test_unstable_optimal_controller_is_replaced_by_a_stable_relaxed_one(cfg, plant):
    """A 330 Hz mode of output gain 0.05 beside the bearing puts a zero pair at
    ≈ 8.9 ± 299j Hz; the optimal central controller then has a pole pair in the RHP (the
    closed loop is stable): the controller returned is stable, at the first relaxed level
    that gives one, and says so."""
    G = parallel_mode(plant, 330.0, 0.05, 0.05)
    z = _rhp_zeros_hz(G)
    assert len(z) == 2 and np.all(np.abs(z.imag) > 250) and np.all(z.real < 0.05 * np.abs(z))
    syn = hinf.synthesize(G, cfg.weights, cfg.highpass)
    assert syn.relaxed, "the optimal controller was stable: nothing to test"
    assert [r["controller_stable"] for r in syn.relaxed] == \
        [False] * (len(syn.relaxed) - 1) + [True]
    last = syn.relaxed[-1]
    assert syn.gamma == pytest.approx(last["gamma"]) and syn.gamma > syn.gamma_optimal
    assert last["gamma"] == pytest.approx(syn.gamma_optimal * last["factor"])
    assert _max_re(syn.K_tilde.A) < 0 and _max_re(syn.K.A) < 0
    assert robustness.is_stable(G, syn.K)
    # the optimal one was unstable by itself (at the optimum), its closed loop was not
    P = hinf.generalized_plant(hinf._freq_scale(G * syn.H, hinf.OMEGA_SCALE),
                               hinf._freq_scale(three_level(cfg.weights.W_p, 2),
                                                hinf.OMEGA_SCALE),
                               hinf._freq_scale(three_level(cfg.weights.W_u, 2),
                                                hinf.OMEGA_SCALE), cfg.weights.W_d)
    g_opt, K_opt = hinf._sb10ad(P, 2, 2)
    assert g_opt == pytest.approx(syn.gamma_optimal)
    assert _max_re(K_opt.A) > 0
    assert robustness.is_stable(G, syn.H * hinf._unscale(K_opt, hinf.OMEGA_SCALE))


def test_plain_plant_keeps_the_optimal_controller(cfg, plant):
    syn = hinf.synthesize(plant, cfg.weights, cfg.highpass)
    assert syn.relaxed == [] and syn.gamma == syn.gamma_optimal
    assert _max_re(syn.K.A) < 0


def test_truncation_finds_a_stable_order_on_such_a_plant(cfg, plant, tmp_path):
    """The paper's route on that plant: with the stable full-order controller some order is
    stable in closed loop, stable itself and within 10 % in band (with the optimal one every
    order kept its unstable pair: 'K(z) itself unstable')."""
    G = parallel_mode(plant, 330.0, 0.05, 0.05)
    res = pipeline.design_controller(G, cfg)
    assert res.relaxed and res.gamma == res.gamma_full > res.gamma_full_optimal
    assert res.stable_discrete and res.band_error <= 0.1
    assert np.max(np.abs(np.linalg.eigvals(res.K_z.A))) < 1.0
    s = res.summary()
    assert s["gamma_full_order_optimal"] == res.gamma_full_optimal
    assert s["full_order_relaxed"][-1]["controller_stable"] is True
    from rigd.design.figures import design_report

    design_report(tmp_path, cfg, res)                    # the design report says it
    text = (tmp_path / "index.html").read_text()
    assert "unstable by itself" in text and f"{res.gamma_full_optimal:.3f}" in text


def test_reduction_at_resonance_counts_the_damping_band_only(cfg, plant):
    """A lightly damped mode outside the damping band (330 Hz) is listed with σ̄(S_o) there,
    not counted in the reductions at the resonances; the bearing modes in the band are."""
    from rigd.design import discretize

    G = parallel_mode(plant, 330.0, 0.05, 0.02)
    syn = hinf.synthesize(G, cfg.weights, cfg.highpass)
    Kz = discretize.tustin(syn.K, cfg.fs_hz, cfg.discretization.prewarp_hz)
    band = tuple(cfg.robustness.band_hz)
    f = robustness.default_freqs(cfg.fs_hz)
    r, _ = robustness.assess(G, Kz, f, band, cfg.robustness.low_hz)
    f_all = robustness.resonances(robustness.match_domain(G, Kz))
    assert np.any(np.abs(f_all - 330.0) < 5)          # the mode is a resonance of G ...
    assert r.resonance_outside_band_hz == pytest.approx([x for x in f_all if x > band[1]])
    assert all(band[0] <= x <= band[1] for x in r.resonance_hz) and len(r.resonance_hz) >= 2
    S_in = robustness.sensitivity_sigma(robustness.match_domain(G, Kz), Kz,
                                        np.array(r.resonance_hz))
    assert r.reduction_at_resonance == pytest.approx(1 / S_in.max())   # ... not counted
    S_out = robustness.sensitivity_sigma(robustness.match_domain(G, Kz), Kz,
                                         np.array(r.resonance_outside_band_hz))
    assert r.sigma_at_resonance_outside_band == pytest.approx(list(S_out))
