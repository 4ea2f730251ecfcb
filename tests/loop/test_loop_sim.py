"""The loop on the simulated plant in lock-step: Eq. 1 in the loop, PD valve step, K∞ blending."""

from __future__ import annotations

import numpy as np
from loop_helpers import make_plant

from rigd.controller import Controller
from rigd.frame import REC
from rigd.loop.loop import ControlLoop
from rigd.loop.sim import simulate_record
from rigd.rigconfig import default_config

SETTLING_S = 2.0e-3   # documented in docs/loop.md: 2 % settling of one valve under its PD loop


def test_eq1_holds_in_every_recorded_frame():
    rng = np.random.default_rng(0)
    exc = rng.uniform(-2, 2, size=(2000, 2))
    r = simulate_record(None, exc, seed=1)
    c = r.columns
    np.testing.assert_array_equal(c["x_x"], exc[:, 0])
    np.testing.assert_array_equal(c["r_x"], exc[:, 0])      # K∞ off: r = excitation
    np.testing.assert_array_equal(c["r_p1"], 5.0 + c["r_y"])
    np.testing.assert_array_equal(c["r_p2"], 5.0 + c["r_x"])
    np.testing.assert_array_equal(c["r_p3"], 5.0 - c["r_y"])
    np.testing.assert_array_equal(c["r_p4"], 5.0 - c["r_x"])
    np.testing.assert_array_equal(c["u_x"], c["y_p2"] - c["y_p4"])
    np.testing.assert_array_equal(c["u_y"], c["y_p1"] - c["y_p3"])
    assert np.all(np.diff(c["seq"]) == 1)
    assert np.all((c["v_1"] >= 0) & (c["v_1"] <= 10))


def test_valve_follows_reference_step_within_settling_time():
    from rigd_drivers.plant import physics as phys

    exc = np.zeros((300, 2))
    exc[:, 0] = 1.0                       # r_x step: r_p2 = r0 + 1 V
    r = simulate_record(None, exc, pre=100, seed=3)
    y = r.columns["y_p2"]
    assert r.columns["r_p2"][99] == 5.0 and r.columns["r_p2"][100] == 6.0
    y0, yf = y[:100].mean(), y[-100:].mean()
    v = default_config().config.valves[1]
    model = phys.valve_closed_loop(phys.valve_params()[1], kp=v.kp, kd=v.kd, tau_d=v.tf_s,
                                   kff=v.kff)
    gain = phys.step_metrics(model)["static_gain"]
    assert abs((yf - y0) - gain) < 0.01                     # static gain of the PD loop
    outside = np.nonzero(np.abs(y[100:] - yf) > 0.02 * (yf - y0))[0]
    settle_s = (outside[-1] + 1) / r.fs
    assert settle_s <= SETTLING_S


def _kick_loop(cfg_over=None, ctrl=None):
    cfg = default_config(clock={"mode": "lockstep"}, **(cfg_over or {}))
    plant = make_plant()
    return ControlLoop(cfg, plant, controller=ctrl), plant


def _enable_run(ramp_s):
    D = np.array([[1.0, 0.0], [0.0, 1.0]])
    ctrl = Controller(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), D, 5000.0)
    loop, plant = _kick_loop({"loop": {"k_ramp_s": ramp_s}}, ctrl)
    with loop:
        loop.run_cycles(1000)
        plant.impact("x", 30.0, 0.001)
        loop.run_cycles(20)
        res = loop.run_segment(np.zeros((100, 2)), record="memory", pre=50,
                               events=[(0, lambda: loop.enable_controller(True))])
    return res.frames


def test_enabling_kinf_mid_run_makes_no_jump():
    hard = _enable_run(0.0)       # no blend: shows the jump a naive switch makes
    soft = _enable_run(0.05)
    i = 50                        # first cycle with K∞ requested on
    kx = REC["k_x"]
    assert np.all(hard[:i, kx] == 0) and np.all(soft[:i, kx] == 0)
    jump_hard = abs(hard[i, kx] - hard[i - 1, kx])
    jump_soft = abs(soft[i, kx] - soft[i - 1, kx])
    assert jump_hard > 0.2                    # the shaft is moving: K∞ has something to say
    assert jump_soft < 0.05 * jump_hard
    assert soft[i, REC["k_on"]] == 1.0


def test_controller_swap_while_enabled_is_bumpless():
    eye = np.eye(2)    # two gentle first-order K∞: the closed loop stays stable
    c1 = Controller(0.9 * eye, 0.1 * eye, 0.05 * eye, 0.0 * eye, 5000.0)
    c2 = Controller(0.5 * eye, 0.5 * eye, -0.08 * eye, 0.02 * eye, 5000.0)
    loop, plant = _kick_loop(None, c1)
    with loop:
        loop.enable_controller(True)
        loop.run_cycles(1500)
        plant.impact("y", 30.0, 0.001)
        loop.run_cycles(10)
        loop.load_controller(c2)
        res = loop.run_segment(np.zeros((1500, 2)), record="memory")
        st = loop.status()
    assert st["fault"]["code"] == 0, st["fault"]
    k = res.frames[:, [REC["k_x"], REC["k_y"]]]
    # blend out, swap, blend in: no step larger than a cycle of ramp plus motion
    assert np.max(np.abs(np.diff(k, axis=0))) < 0.05
    assert st["controller"]["enabled"] and st["controller"]["blend"] == 1.0
    assert loop.controller is c2


def test_simulate_record_is_deterministic_per_seed():
    exc = np.random.default_rng(2).uniform(-1, 1, (500, 2))
    a = simulate_record(None, exc, seed=11)
    b = simulate_record(None, exc, seed=11)
    c = simulate_record(None, exc, seed=12)
    np.testing.assert_array_equal(a.columns["e_x"], b.columns["e_x"])
    assert not np.array_equal(a.columns["e_x"], c.columns["e_x"])
