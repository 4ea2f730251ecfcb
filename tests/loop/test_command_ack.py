"""Command tickets: a command is *applied* only once the loop has acted on it, so that an
operator's ``load``/``enable``/``op``/``reset`` reply is followed by a ``status`` that shows it.
(CI once saw ``rigd ctl load`` answered while ``status`` still named the old controller.)"""

from __future__ import annotations

import threading

import numpy as np
from loop_helpers import make_plant

from rigd.controller import Controller
from rigd.loop import layout as L
from rigd.loop.commands import CommandQueue
from rigd.loop.loop import ControlLoop
from rigd.loop.state import KernelState, PackedController
from rigd.rigconfig import default_config


def _ctrl(gain: float) -> Controller:
    eye = np.eye(2)
    return Controller(0.9 * eye, 0.1 * eye, gain * eye, 0.0 * eye, 5000.0)


def _queue():
    state = KernelState(default_config().config, ring_frames=64)
    return state, CommandQueue(state)


def test_a_ticket_is_applied_only_after_the_loop_took_it():
    state, q = _queue()
    t1 = q.reset()
    t2 = q.enable(True)
    assert not q.applied(t1) and not q.applied(t2)
    q.apply()
    assert q.applied(t1) and q.applied(t2)
    assert state.st[L.S_K_TARGET] == 1.0


def test_tickets_hold_whatever_order_producers_append_in():
    """Two producer threads: one took its ticket, the other's command reached the queue and
    the loop first. The later command being applied says nothing of the earlier one (a
    counter of the last ticket taken off the queue once said it did)."""
    _, q = _queue()
    t1 = q.reset()
    t2 = q.enable(True)
    late = q.queue.popleft()                    # t1's producer has not appended yet
    q.apply()
    assert q.applied(t2) and not q.applied(t1)
    q.queue.append(late)
    q.apply()
    assert q.applied(t1)


def test_a_deferred_swap_is_applied_when_swapped_in_not_when_queued():
    state, q = _queue()
    c1, c2 = _ctrl(0.05), _ctrl(-0.05)
    state.st[L.S_K_TARGET] = 1.0
    state.st[L.S_RAMP] = 0.5                    # K∞ half blended in
    t = q.controller(PackedController(c2))
    q.apply()
    assert not q.applied(t)                     # blending out first
    assert state.st[L.S_K_TARGET] == 0.0 and state.controller is not c2
    state.st[L.S_RAMP] = 0.0                    # the cycles blended it out
    q.apply()
    assert q.applied(t) and state.controller is c2
    assert state.st[L.S_K_TARGET] == 1.0        # and back in
    del c1


def test_a_second_load_during_the_blend_out_keeps_the_re_enable():
    state, q = _queue()
    c2, c3 = _ctrl(-0.05), _ctrl(0.02)
    state.st[L.S_K_TARGET] = 1.0
    state.st[L.S_RAMP] = 0.5
    t2 = q.controller(PackedController(c2))
    q.apply()
    t3 = q.controller(PackedController(c3))
    q.apply()
    assert q.applied(t2) and not q.applied(t3)  # superseded, the newer one waits
    state.st[L.S_RAMP] = 0.0
    q.apply()
    assert q.applied(t3) and state.controller is c3
    assert state.st[L.S_K_TARGET] == 1.0        # K∞ was on before the first load: on again


def test_a_running_loop_shows_a_loaded_controller_once_wait_applied_returns():
    cfg = default_config(clock={"mode": "lockstep"}, loop={"k_ramp_s": 0.02})
    loop = ControlLoop(cfg, make_plant(), controller=_ctrl(0.05))
    with loop:
        loop.start()                            # lock-step, continuously, in its own thread
        t = loop.enable_controller(True)
        assert loop.wait_applied(t)
        assert loop.status()["controller"]["requested"]
        for i in range(5):                      # each load swaps while K∞ is in: deferred
            c = _ctrl(0.01 * (i + 1))
            t = loop.load_controller(c)
            assert loop.wait_applied(t), i
            assert loop.controller is c, i
        t = loop.set_operating_point(2500.0, 5.0)
        assert loop.wait_applied(t)
        loop.stop()


def test_wait_applied_returns_false_at_once_when_no_cycles_run():
    cfg = default_config(clock={"mode": "lockstep"})
    loop = ControlLoop(cfg, make_plant())
    with loop:
        t = loop.load_controller(_ctrl(0.05))
        done = threading.Event()
        result = []

        def waiter():
            result.append(loop.wait_applied(t, timeout_s=60.0))
            done.set()

        threading.Thread(target=waiter, daemon=True).start()
        assert done.wait(30.0)                  # not the 60 s bound: nothing runs cycles
        assert result == [False]
        loop.run_cycles(1)                      # the next run applies it
        assert loop.applied(t)
