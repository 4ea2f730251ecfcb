"""Invalid samples are recorded as NaN, never as the held value, while the loop runs safely on
the held values (the real loop in lock-step, the simulated plant behind a driver boundary
that stops delivering: tests/service/faultkit.py); every fault is listed, in words."""

import numpy as np
from daemon_helpers import make_config
from faultkit import Injector, assert_safe_after_fault, controller_file, lockstep_fault

from rigd.driver import STATUS_DISCONNECT, STATUS_TIMEOUT
from rigd.frame import IN_SEQ, IN_STATUS, REC
from rigd.loop import faults as FC
from rigd.loop.app import build_drivers
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import load_config


class _Held:
    """A driver that lost its device: the frame keeps its last values and says so."""

    def __init__(self, bits):
        self.bits = bits
        self.held = None

    def __call__(self, frame_in):
        if self.held is None:
            self.held = frame_in.copy()
        frame_in[:] = self.held
        frame_in[IN_STATUS] = self.bits


def test_a_disconnected_driver_is_recorded_nan_and_the_loop_runs_on_held_values(tmp_path):
    fr, faults, _ = lockstep_fault(tmp_path, _Held(STATUS_DISCONNECT | STATUS_TIMEOUT),
                                   at=1500, n=4000, supervisor={"stale_frames": 0})
    i = assert_safe_after_fault(fr, FC.DRIVER_STATUS, armed_at=1500, max_latency=1,
                                faults=faults)
    for ch in ("e_x", "e_y", "y_p1", "y_p4", "phi", "f_x", "u_x", "u_y"):
        assert np.all(np.isnan(fr[i:, REC[ch]])), ch          # invalid, not held
        assert np.all(np.isfinite(fr[:i, REC[ch]])), ch
    # the loop itself ran on the held values: drives and references finite, never NaN
    for ch in ("v_1", "v_2", "v_3", "v_4", "r_p1", "k_x", "r_x"):
        assert np.all(np.isfinite(fr[:, REC[ch]])), ch
    assert faults[0]["name"] == "driver_status"
    assert "disconnected" in faults[0]["text"] and "status bits" not in faults[0]["text"]


def test_a_disconnect_while_another_fault_is_latched_is_listed_too(tmp_path):
    lc = load_config(make_config(tmp_path, supervisor={"stale_frames": 0}))
    fast, slow, hz = build_drivers(lc)
    inj = Injector(fast, _Held(STATUS_DISCONNECT))
    loop = ControlLoop(lc, inj, slow_drivers=slow, slow_poll_hz=hz,
                       controller=controller_file(tmp_path), clock="lockstep")
    with loop:
        loop.run_cycles(200)
        loop.trip(FC.OPERATOR_SAFE)
        loop.run_cycles(200)
        inj.armed = True
        loop.run_cycles(200)
        faults = loop.faults()
        st = loop.status()
    assert [f["name"] for f in faults] == ["operator_safe", "driver_status"], faults
    assert "disconnected" in faults[1]["text"]
    assert st["fault"]["name"] == "operator_safe"          # the first still holds the latch


def test_a_repeated_frame_is_not_recorded_as_a_new_sample(tmp_path):
    """A frame whose driver counter did not advance is the held one: NaN in the record."""
    held = {}

    def freeze_seq(frame_in):
        held.setdefault("seq", frame_in[IN_SEQ])
        frame_in[IN_SEQ] = held["seq"]

    fr, faults, _ = lockstep_fault(tmp_path, freeze_seq, at=1500, n=3000,
                                   supervisor={"stale_frames": 4})
    i = assert_safe_after_fault(fr, FC.STALE_FRAME, armed_at=1500, faults=faults)
    assert np.all(np.isnan(fr[i - 4:i, REC["e_x"]]))   # the repeats before the latch, too
    assert np.all(np.isfinite(fr[:1501, REC["e_x"]]))          # a new frame, then repeats
