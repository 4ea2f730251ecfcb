"""Valves under the suggested PD loop: the plant matches the documented closed loop exactly."""

import control
import numpy as np
import pytest

from rigd.configio import read_yaml, validate
from rigd.frame import IN_YP1
from rigd_drivers.plant import physics as phys
from rigd_drivers.sim.driver import SimPlantDriver
from rigd_drivers.sim.options import PlantOptions

QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}


def test_valve_step_under_pd_follows_documented_closed_loop(pd):
    d = SimPlantDriver(QUIET)
    n_pre, n = 500, 100
    r = np.full((n_pre + n, 4), 5.0)
    r[n_pre:] = 5.5                                   # +0.5 V reference step on every valve
    frames = pd(d, r)
    y = frames[:, IN_YP1:IN_YP1 + 4]
    dy = y[n_pre - 1:] - y[n_pre - 1]                 # dy[0]: sample the step is applied at
    for i, v in enumerate(phys.valve_params()):
        H = phys.valve_closed_loop(v)
        _, s = control.step_response(H, T=np.arange(n + 1) / 5000.0)
        expect = 0.5 * np.asarray(s).ravel()
        assert np.allclose(dy[:, i], expect, atol=1e-9), i
        fin = expect[-1]
        late = np.nonzero(np.abs(dy[:, i] - fin) > 0.02 * abs(fin))[0]
        assert late.max() + 1 <= 8                    # settled (2 %) within 1.6 ms
        assert dy[:, i].max() < 1.02 * fin            # no overshoot to speak of


def test_shipped_sim_config_plant_section_is_complete():
    loaded = read_yaml("config/sim.yaml")
    opts = validate(loaded, PlantOptions, section=("plant",))
    sec = loaded.data["plant"]
    assert set(sec["effects"]) == set(type(opts.effects).model_fields)   # every effect listed
    assert opts.effects.enabled() == []                                   # all off as shipped
    assert opts == PlantOptions()                                         # = documented defaults


@pytest.mark.parametrize("name, hold", [("delay", 5), ("cubic_stiffness", 5), ("extra_mode", 5),
                                        ("hysteresis", 5), ("runout", 5), ("creep", 500)])
def test_each_effect_alone_changes_the_closed_loop_record(name, hold, pd):
    """Switched on alone at its default strength, an effect changes an identification record
    (PRBS ±1 V; multi-level steps held 0.1 s for creep, which is slow) by more than 2 %."""
    rng = np.random.default_rng(1)
    n = 3000
    lv = np.repeat(rng.uniform(-1.0, 1.0, size=(n // hold + 1, 2)), hold, axis=0)[:n]
    if hold == 5:
        lv = np.sign(lv)
    r = np.column_stack([5 + lv[:, 1], 5 + lv[:, 0], 5 - lv[:, 1], 5 - lv[:, 0]])
    opts = {**QUIET, "omega_rpm": 3000.0}
    base = pd(SimPlantDriver(opts), r)
    on = pd(SimPlantDriver({**opts, "effects": {name: {"enabled": True}}}), r)

    def channels(f):
        y = f[:, IN_YP1:IN_YP1 + 4]
        return np.column_stack([f[:, 0], f[:, 1], y[:, 1] - y[:, 3], y[:, 0] - y[:, 2]])

    c0, c1 = channels(base), channels(on)
    change = ((c1 - c0).std(axis=0) / c0.std(axis=0)).max()
    assert change > 0.02, change
