"""The SAFE word (rigd.loop.safeword): taken by the cycle itself, acknowledged with the cycle it
latched at; commands sent before a SAFE, past their deadline, cancelled by their caller, or an
``enable`` while a fault is latched are dropped — applied when answered, or never."""

from __future__ import annotations

import numpy as np
from loop_helpers import make_plant

from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop.commands import DROP_FAULT, DROP_LATE, DROP_SAFE, CommandQueue
from rigd.loop.loop import ControlLoop
from rigd.loop.safeword import W_ACK_N, W_REQ, SafeWord
from rigd.loop.state import KernelState
from rigd.rigconfig import default_config
from rigd.service.safe_request import SafeWordClient


def _loop():
    cfg = default_config(clock={"mode": "lockstep", "batch_cycles": 64})
    return ControlLoop(cfg, make_plant())


def test_a_request_latches_operator_safe_in_the_next_cycle_and_is_acknowledged():
    loop = _loop()
    with loop:
        loop.run_cycles(100)
        assert loop.state.fault == 0
        c0 = loop.request_safe()
        assert c0 == 99                          # the cycle that ran last wrote its number
        loop.run_cycles(1)
        ack = loop.wait_safe(c0, 0.0)
        assert ack is not None and ack["latched_at"] == 100
        assert ack["fault"]["name"] == "operator_safe" and ack["fault"]["seq"] == 100
        assert loop.status()["fault"]["seq"] == 100
        assert loop.safe_generation == 1
        # the same value again is no new request; a fresh one is (first fault still wins)
        loop.run_cycles(10)
        assert loop.safe_generation == 1
        c1 = loop.request_safe()
        loop.run_cycles(1)
        assert loop.wait_safe(c1, 0.0)["latched_at"] == c1 + 1
        assert loop.safe_generation == 2 and loop.status()["fault"]["seq"] == 100


def test_nothing_written_into_the_page_can_hide_a_request():
    """The value last taken lives in the loop's private state, not in the shared page."""
    loop = _loop()
    with loop:
        loop.run_cycles(10)
        loop.request_safe()
        loop.safe.word[W_ACK_N] = 10**6          # a writer falsifying the acknowledgement
        loop.run_cycles(1)
        assert loop.state.fault == FC.OPERATOR_SAFE


def test_the_word_shared_as_a_file_is_taken_from_another_mapping(tmp_path):
    loop = _loop()
    path = loop.safe.attach_file(str(tmp_path / "rigd.sock.safe"), 0o640)
    assert (tmp_path / "rigd.sock.safe").stat().st_mode & 0o777 == 0o640
    with loop:
        loop.run_cycles(50)
        client = SafeWordClient(str(tmp_path / "rigd.sock"))
        c0 = client.request()
        assert client.ack(c0) is None
        loop.run_cycles(1)
        ack = client.ack(c0)
        client.close()
    assert ack["latched_at"] == c0 + 1 and ack["fault"]["name"] == "operator_safe"
    loop.safe.detach_file()
    assert not (tmp_path / "rigd.sock.safe").exists() and path


def test_safe_drops_the_commands_queued_before_it():
    loop = _loop()
    with loop:
        loop.run_cycles(20)
        t_op = loop.set_operating_point(1000.0, 4.0)
        t_reset = loop.reset_fault()
        loop.request_safe()                     # after both were queued, before a cycle
        loop.run_cycles(5)
        assert t_op.dropped == DROP_SAFE and not t_op.applied
        assert t_reset.dropped == DROP_SAFE and loop.state.fault == FC.OPERATOR_SAFE
        assert loop.status()["last_frame"]["omega_rpm"] != 1000.0
        # sent after the SAFE: applied
        t = loop.reset_fault()
        loop.run_cycles(5)
        assert t.applied and loop.state.fault == 0


def test_enable_while_a_fault_is_latched_is_dropped_with_a_reason():
    loop = _loop()
    with loop:
        loop.run_cycles(10)
        loop.trip(FC.OPERATOR_STOP)
        loop.run_cycles(2)
        t = loop.enable_controller(True)
        loop.run_cycles(2)
        assert t.dropped == DROP_FAULT and loop.state.st[L.S_K_TARGET] == 0.0
        t = loop.enable_controller(False)       # disabling is always allowed
        loop.run_cycles(2)
        assert t.applied


def test_a_cancelled_or_late_command_is_never_applied():
    state = KernelState(default_config().config, ring_frames=64)
    q = CommandQueue(state)
    t = q.enable(True)
    assert t.cancel()                           # its caller gave up first
    late = q.enable(True, deadline=1e-3)        # monotonic 1 ms: long past
    q.apply()
    assert not t.applied and t.dropped == DROP_LATE
    assert late.dropped == DROP_LATE and state.st[L.S_K_TARGET] == 0.0
    t2 = q.reset()
    q.apply()
    assert t2.applied and not t2.cancel()       # the loop decided first: cancel says so


def test_a_fresh_word_has_no_pending_request():
    w = SafeWord()
    assert w.word[W_REQ] == 0 and w.acknowledged_at() == -1
    assert np.all(w.word[3:] == 0)
