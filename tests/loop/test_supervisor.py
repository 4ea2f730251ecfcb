"""Supervisor: representative trips put the loop in the safe state within the cycle and latch."""

from __future__ import annotations

import numpy as np
import pytest
from loop_helpers import InjectingDriver, make_plant

from rigd.frame import IN_E_X, IN_OMEGA, IN_PHI, IN_SEQ, IN_YP1, REC
from rigd.loop import cycle as K
from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import default_config

AT = 300   # cycle at which the fault is injected


def _run(inject=None, fail_at=None, n=600, **cfg):
    config = default_config(clock={"mode": "lockstep"}, **cfg)
    drv = InjectingDriver(make_plant(), inject, fail_at)
    loop = ControlLoop(config, drv)
    q = loop.subscribe()
    exc = np.full((n, 2), 0.3)           # excitation on: must be cut by the safe state
    with loop:
        res = loop.run_segment(exc, record="memory")
        status = loop.status()
    events = []
    while not q.empty():
        events.append(q.get())
    return res.frames, status, events, loop


def _assert_safe_from(frames, i):
    f = frames[i:]
    assert np.all(f[:, REC["x_x"]] == 0) and np.all(f[:, REC["r_x"]] == 0)
    for j in (1, 2, 3, 4):
        assert np.all(f[:, REC[f"r_p{j}"]] == 5.0)
    assert np.all(f[:, REC["k_on"]] == 0)
    v = f[:, [REC["v_1"], REC["v_2"], REC["v_3"], REC["v_4"]]]
    assert np.all(np.isfinite(v)) and np.all((v >= 0) & (v <= 10))
    assert np.all(frames[:i, REC["x_x"]] == 0.3)      # normal before the fault


def _first_fault(frames):
    idx = np.nonzero(frames[:, REC["fault"]])[0]
    assert len(idx), "no fault latched"
    return int(idx[0]), int(frames[idx[0], REC["fault"]])


def test_nan_sensor_trips_in_the_same_cycle_and_latches():
    def inject(f, n):
        if n == AT:
            f[IN_E_X] = np.nan                     # one bad sample only
    frames, status, events, _ = _run(inject)
    i, code = _first_fault(frames)
    assert (i, code) == (AT, FC.SENSOR_NAN)
    _assert_safe_from(frames, i)
    assert np.all(frames[i:, REC["fault"]] == FC.SENSOR_NAN)   # latched after the cause left
    assert status["fault"]["name"] == "sensor_nan" and "e_x" in status["fault"]["text"]
    assert [e["code"] for e in events] == [FC.SENSOR_NAN]     # reported once


def test_stale_frame_trips_after_configured_repeats():
    frozen = {}

    def inject(f, n):
        if n >= AT:
            f[IN_SEQ] = frozen.setdefault("seq", f[IN_SEQ])
    frames, *_ = _run(inject)
    i, code = _first_fault(frames)
    assert code == FC.STALE_FRAME
    assert i == AT + 4                     # stale_frames: 3 repeats tolerated, the 4th trips
    _assert_safe_from(frames, i)


def test_stuck_valve_trips_valve_tracking():
    def inject(f, n):
        if n >= AT:
            f[IN_YP1 + 2] = 0.5                # valve 3 stuck far from its ~5 V reference
    frames, status, *_ = _run(inject)
    i, code = _first_fault(frames)
    assert code == FC.VALVE_TRACKING and "valve 3" in status["fault"]["text"]
    assert i == AT + 250                   # valve_error_s 0.05 s at 5 kHz
    _assert_safe_from(frames, i)


def test_lost_encoder_while_turning():
    def inject(f, n):
        f[IN_OMEGA] = 3000.0                   # turning: phi must advance every cycle
        f[IN_PHI] = (0.1 * min(n, AT)) % (2 * np.pi)
    frames, *_ = _run(inject)
    i, code = _first_fault(frames)
    assert code == FC.ENCODER_LOST and AT + 40 <= i <= AT + 60   # encoder_frozen_s 0.01 s


def test_driver_exception_trips():
    frames, status, events, loop = _run(fail_at=AT)
    i, code = _first_fault(frames)
    assert code == FC.DRIVER_EXCEPTION and i == AT
    assert "device unplugged" in events[0]["text"]


def test_shaft_displacement_beyond_film_gap_fraction():
    def inject(f, n):
        if n >= AT:
            f[IN_E_X] = 21.0                   # > 0.8 x 25 µm
    frames, *_ = _run(inject)
    assert _first_fault(frames) == (AT, FC.SHAFT_DISPLACEMENT)


def test_reset_fault_clears_only_when_cause_is_gone():
    state = {"bad": True}

    def inject(f, n):
        if state["bad"] and n >= 10:
            f[IN_E_X] = np.nan
    config = default_config(clock={"mode": "lockstep"})
    loop = ControlLoop(config, InjectingDriver(make_plant(), inject))
    with loop:
        loop.run_cycles(50)
        assert loop.status()["fault"]["code"] == FC.SENSOR_NAN
        loop.reset_fault()
        loop.run_cycles(5)
        assert loop.status()["fault"]["code"] == FC.SENSOR_NAN     # cause persists: latched again
        state["bad"] = False
        loop.reset_fault()
        loop.run_cycles(5)
        assert loop.status()["fault"]["code"] == 0
        assert [f["code"] for f in loop.faults()] == [FC.SENSOR_NAN, FC.SENSOR_NAN]


def test_full_ring_on_the_realtime_path_is_counted_and_latched():
    prm, st = np.zeros(L.N_PRM), np.zeros(L.N_ST)
    prm[L.P_RING_N], prm[L.P_FS], prm[L.P_VMAX] = 4, 5000.0, 10.0
    prm[L.P_CAL_G:L.P_CAL_G + 13] = 1.0
    ring = np.zeros((4, len(REC)))
    st[L.S_W], st[L.S_RD] = 4.0, 0.0     # writer has not freed anything
    K.cycle(np.zeros(13), prm, st, np.zeros(4), ring, 0.0, 0.0)
    assert st[L.S_DROPPED] == 1 and st[L.S_FAULT] == FC.RECORDER_OVERFLOW
    assert st[L.S_W] == 4.0                # nothing overwritten


@pytest.mark.parametrize("code", sorted(FC.FAULTS))
def test_fault_codes_have_stable_names(code):
    assert FC.fault_name(code) == FC.FAULTS[code][0]
    assert FC.fault_text(code)
