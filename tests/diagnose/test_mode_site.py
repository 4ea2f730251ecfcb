"""Effects at the ``mode`` site (rigd.effects.mode_site): a joint, a clearance or a cubic
spring on one mode of a modal LTI base, on the jointed-structure generator
(tests/gen/joint.py): named at the right mode by the default screening, better at another
force level than the linear model, refused with the reason on a base without modes."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from rigd.diagnose.engine import diagnose_data
from rigd.effects import REGISTRY, resolve
from rigd.effects.compose import Composed, carries
from rigd.ident.greybox.mechanical import generic_structure
from rigd.ident.iddata import IdData
from rigd.ident.lti import nonlinear_mode as NM
from rigd.ident.lti.statespace import StateSpaceModel
from rigd.ident.pem import fit
from tests.gen import joint

#: three modes in the multisine's band (the generator's first three), short records
MODES = joint.FIVE_MODES[:3]
N_PERIOD = 2048

#: two joints of other parameters, modes, levels and seeds (the method is tuned to none)
CASES = {
    "iwan": dict(joint="iwan", joint_mode=0, seed=0, level=3.0, other=1.0),
    "jenkins": dict(joint="iwan", joint_mode=1, seed=4, level=2.0, other=6.0, n_slip=1,
                    k_ratio=0.4, f_slip=2.0),
    "clearance": dict(joint="clearance", joint_mode=0, seed=2, level=3.0, other=8.0),
}


def _data(g) -> IdData:
    return IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))


@functools.cache
def _case(name: str):
    """(record at the case's level, at the other level, the base fitted on the first)."""
    kw = dict(CASES[name])
    level, other = kw.pop("level"), kw.pop("other")
    rec = [joint.joint_structure(level=lv, modes=MODES, n=N_PERIOD, periods=2,
                                 n_outputs=1, **kw) for lv in (level, other)]
    d = _data(rec[0])
    m = StateSpaceModel(["force"], ["acc1"], d.fs, n_complex=len(MODES), hold="foh",
                        feedthrough=True)
    m.set_record(2 * N_PERIOD // 3 * 2)
    est = d.slice(0, 2 * d.n // 3)
    th = fit(m, est, method="oe", theta0=m.theta0(est)).theta
    return rec[0], rec[1], m, th


def _error(structure, theta, g) -> float:
    """Error energy of ``structure`` on the steady (second) period of ``g``."""
    d = _data(g)
    r = (d.y - np.asarray(structure.simulate(theta, d)))[N_PERIOD:]
    return float(np.sum(r ** 2))


@pytest.mark.parametrize("name", ["iwan", "jenkins", "clearance"])
def test_mode_effect_named_at_its_mode_and_better_at_another_force_level(name):
    g, other, m, th = _case(name)
    d = _data(g)
    sd = diagnose_data(d, "generic", m, base_theta=th, max_steps=1,
                       record_meta={"units": {"force": "N", "acc1": "m/s^2"}})
    top = sd.findings[0]
    want = "clearance" if CASES[name]["joint"] == "clearance" else "joint"
    assert top.significant and top.effect == want, [(f.effect, f.significant, f.score)
                                                   for f in sd.findings[:4]]
    truth = g.truth
    f_true = joint.mode_near(g, MODES[truth["joint_mode"]][0] * 1.05)[0]
    assert abs(top.evidence["mode_hz"] / f_true - 1) < 0.03
    assert f"{top.evidence['mode_hz']:.3g} Hz mode" in top.explanation
    ref = sd.refits[top.effect]
    # the mode is the model's: a held parameter of the refit at the named mode
    k = ref.structure.names.index(f"{top.effect}_mode")
    assert ref.theta[k] == top.evidence["mode"] == truth["joint_mode"] + 1
    # held out at another force level (2.7x or 3x the estimation level, or a third of it):
    # the linear model's error falls by at least a third; a wrong block fitted at one level
    # does not carry to another
    assert _error(m, th, other) >= 1.5 * _error(ref.structure, ref.theta, other)


def test_mode_effects_refused_on_a_base_without_modes_with_the_reason():
    mech = generic_structure(["force"], ["acc1"])
    for nm in ("joint", "clearance", "mode_cubic"):
        why = REGISTRY[nm].not_offered(mech)
        assert why is not None and nm in why and "mode" in why and "complex-pair" in why
        with pytest.raises(ValueError, match="modal"):
            Composed(mech, [REGISTRY[nm]])
    one_real = StateSpaceModel(["u"], ["y"], 100.0, n_real=1)
    assert "mode" not in carries(one_real)
    assert REGISTRY["joint"].not_offered(one_real) is not None
    # one mode effect per model
    m = StateSpaceModel(["u"], ["y"], 100.0, n_complex=2)
    assert "mode" in carries(m) and REGISTRY["joint"].not_offered(m) is None
    assert "beside" in REGISTRY["clearance"].not_offered(REGISTRY["joint"].extend(m))


def _one_mode(hold="foh"):
    m = StateSpaceModel(["u"], ["y"], 200.0, n_complex=1, hold=hold, output_offsets=False)
    wn = 2 * np.pi * 9.0
    lam = [complex(-0.02 * wn, wn * np.sqrt(1 - 0.02 ** 2))]
    th = m.pack(lam, np.array([[0.7], [-0.4]]), np.array([[1.0, 0.0]]))
    rng = np.random.default_rng(1)
    u = np.convolve(rng.standard_normal(1200), np.ones(4) / 4, "same")[:, None]
    return m, th, IdData(u, np.zeros((1200, 1)), 200.0, ["u"], ["y"])


def test_mode_coordinate_obeys_the_companion_equation(hold="foh"):
    """q of the mode's block: q̈ + 2ζω q̇ + ω² q = u (finite differences), and a law at
    zero size leaves the base's output unchanged."""
    m, th, d = _one_mode(hold)
    info = NM.mode_force(m, th, d, 1)
    f, z = NM.mode_hz(m, th, 1)
    w = 2 * np.pi * f
    q, v, dt = info["q"], info["v"], 1.0 / d.fs
    from scipy.signal import lsim

    # the companion ODE integrated on its own (the input linear between samples)
    t = np.arange(d.n) * dt
    _, q_ref, x = lsim(([1.0], [1.0, 2 * z * w, w ** 2]), d.u[:, 0], t)
    assert np.max(np.abs(q - q_ref)) < 0.01 * np.max(np.abs(q_ref))
    assert np.max(np.abs(v - np.gradient(q_ref, dt))) < 0.1 * np.max(np.abs(v))
    for nm, te in (("joint", [1.0, 0.0, 1.0, 1.0, 0.0]), ("clearance", [1.0, 0.0, 1.0, 0.0]),
                   ("mode_cubic", [1.0, 0.0, 0.0])):
        y = REGISTRY[nm].extend(m).simulate(np.r_[th, te], d)
        assert np.allclose(y, m.simulate(th, d), atol=1e-9 * np.std(y) + 1e-12)
    # a stiff clearance beyond a small gap changes it
    y = REGISTRY["clearance"].extend(m).simulate(np.r_[th, 1.0, 0.5, 1e-3, 0.0], d)
    assert np.max(np.abs(y - m.simulate(th, d))) > 0.05 * np.std(y)


def test_identify_add_joint_fits_it_and_the_model_file_keeps_it(tmp_path):
    """``rigd identify --add joint``: the mode chosen on the fitted base, the model file
    rebuilt into the same model."""
    from rigd.api.modelling import identify
    from rigd.ident.modelfile import load_model

    g = _case("iwan")[0]
    path = tmp_path / "m.yaml"
    idf = identify(g.record(), order=2 * len(MODES), hold="foh", add="joint", out=path)
    sm = idf.model.submodels["generic"]
    par = dict(zip(sm.structure.names, sm.theta))
    assert par["joint_mode"] == g.truth["joint_mode"] + 1 and par["joint_share"] > 0.01
    back = load_model(path, resolve_effects=resolve).submodels["generic"]
    assert back.structure.effects == ["joint"]
    d = _data(g)
    assert np.allclose(back.structure.simulate(back.theta, d), sm.structure.simulate(sm.theta, d))


@pytest.mark.parametrize("nm,te", [("joint", [2.0, 0.3, 0.4, 0.5, 0.02, -0.01]),
                                   ("clearance", [2.0, 0.5, 0.3, 0.0, 0.01])])
def test_a_mode_effect_gives_exact_columns_outside_the_law(nm, te):
    """With a law on mode 2 of a three-mode, two-output base, the output is the base's plus a
    term of mode 2's block alone: the composed model gives exact sensitivities (each is the
    composed simulation's central difference) for every parameter of the other modes, for
    mode 2's output columns C and for the law's direct shares, and none for mode 2's pole,
    B or x0 or the law's own sizes (those are differenced by the fit)."""
    from rigd.effects.compose import compose

    m = StateSpaceModel(["u"], ["y1", "y2"], 200.0, n_complex=3, n_real=1, hold="foh",
                        feedthrough=True)
    m.set_record(1500)
    wn = 2 * np.pi * np.array([4.0, 9.0, 23.0])
    lam = [complex(-0.03 * w, w * np.sqrt(1 - 0.03 ** 2)) for w in wn] + [complex(-30.0, 0)]
    rng = np.random.default_rng(7)
    th = m.pack(lam, rng.standard_normal((7, 1)), rng.standard_normal((2, 7)),
                D=0.1 * rng.standard_normal((2, 1)), x0=0.01 * rng.standard_normal(7))
    d = IdData(rng.standard_normal((1500, 1)), np.zeros((1500, 2)), 200.0, ["u"],
               ["y1", "y2"])
    c = compose(m, [REGISTRY[nm]])
    th_c = np.r_[th, te]
    assert th_c.size == len(c.names)
    idx, dY = c.output_sensitivities(th_c, d)
    names = {c.names[i] for i in idx}
    moved = {"p2_lnf", "p2_zeta", "b3_1", "b4_1", "x0_3", "x0_4"}
    assert names == ({v for v in m.names if v[0] != "k"} - moved) | {f"{nm}_d1", f"{nm}_d2"}
    assert {"p1_lnf", "p3_zeta", "r1_lnf", "b1_1", "d2_1"} <= names
    assert any(v.startswith("c") and v.endswith(("_3", "_4")) for v in names)
    # the law is not idle at this size: mode 2's block does change the output
    assert np.max(np.abs(c.simulate(th_c, d) - m.simulate(th, d))) > 1e-3 * np.std(
        m.simulate(th, d))
    for k, p in enumerate(idx):
        h = 1e-5 * max(1.0, abs(th_c[p]))
        t1, t2 = th_c.copy(), th_c.copy()
        t1[p] += h
        t2[p] -= h
        fd = (c.simulate(t1, d) - c.simulate(t2, d)) / (2 * h)
        assert np.max(np.abs(fd - dY[k])) <= 1e-6 * max(np.max(np.abs(fd)), 1.0), c.names[p]
