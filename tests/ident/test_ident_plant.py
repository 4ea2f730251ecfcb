"""Known parameters through the real loop: records from the simulated plant (rigd.loop.sim)
identified and checked against the plant's true physics (rigd_drivers.plant.physics)."""

import numpy as np
from ident_helpers import prbs

import rigd_drivers.plant.physics as sp
from rigd.ident.workflow import identify_record
from rigd.loop import sim


def _record(omega, p, n, seed, effects=None, excite=True, kind="prbs"):
    rng = np.random.default_rng(seed)
    exc = 0.5 * prbs(n, rng) if excite else np.zeros((n, 2))
    return sim.simulate_record(excitation=exc, seed=seed, omega_rpm=omega, p_inj_bar=p,
                               effects=effects, kind=kind)


def _check_modes(model, omega, p):
    f_true, z_true = sp.bearing_modes(omega, p)
    modes = [m for m in model.submodels["bearing"].readouts["modes"] if "f_n_hz" in m]
    f = np.array([m["f_n_hz"] for m in modes])
    z = np.array([m["zeta"] for m in modes])
    order = np.argsort(f_true)
    np.testing.assert_allclose(f, np.asarray(f_true)[order], rtol=0.005)
    np.testing.assert_allclose(z, np.asarray(z_true)[order], rtol=0.05)


def test_sim_plant_bearing_and_actuator_at_4_bar():
    rec = _record(0.0, 4.0, 24000, 1)
    model = identify_record(rec, "both")
    _check_modes(model, 0.0, 4.0)
    assert min(model.submodels["bearing"].fit_percent["validation"]) >= 95.0
    G0 = np.array(model.submodels["bearing"].readouts["static_gain"])
    np.testing.assert_allclose(np.diag(G0), sp.STATIC_GAIN_UM_PER_V, rtol=0.02)
    # the lumped PD-controlled valve pair is close to, not exactly, second order (Eq. 8);
    # its static gain is checked with the output-error fit
    act = identify_record(rec, "actuator", method="oe").submodels["actuator"]
    for ax in "xy":
        true = float(sp.lumped_actuator_tf(ax).dcgain())
        assert abs(act.readouts["axes"][ax]["gain"] / true - 1) < 0.02
    assert min(act.fit_percent["validation"]) >= 95.0


def test_sim_plant_rotating_with_runout_filter():
    omega, p = 3000.0, 6.0
    rec = _record(omega, p, 24000, 2, effects=["runout"])
    ro = _record(omega, p, 24000, 3, effects=["runout"], excite=False, kind="runout")
    model = identify_record(rec, "bearing", runout=ro)
    _check_modes(model, omega, p)
    with_filter = min(model.submodels["bearing"].fit_percent["validation"])
    assert with_filter >= 95.0
    raw = identify_record(rec, "bearing")
    assert min(raw.submodels["bearing"].fit_percent["validation"]) < with_filter - 1.0
