"""Operating-point changes are prepared outside the loop thread and swapped in O(1).

The simulated plant's parameter block needs two matrix exponentials and allocations; before,
``ControlLoop`` called the driver's ``set_operating_point`` from the loop thread and built it
there. Now the caller's thread builds it and the loop thread only stages the prepared block.
"""

from __future__ import annotations

import threading

import numpy as np
from loop_helpers import make_plant

import rigd_drivers.sim.params as sim_params
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import default_config


def _record_threads(monkeypatch):
    seen: list[str] = []
    real = sim_params.ParamBlocks.__call__

    def build(*a, **k):
        seen.append(threading.current_thread().name)
        return real(*a, **k)

    monkeypatch.setattr(sim_params.ParamBlocks, "__call__", build)
    return seen


def _wait(pred, timeout=20.0):
    ev = threading.Event()
    for _ in range(int(timeout / 0.005)):
        if pred():
            return True
        ev.wait(0.005)
    return pred()


def test_realtime_loop_thread_never_prepares_an_operating_point(monkeypatch):
    cfg = default_config(clock={"mode": "realtime", "spin_us": 0.0},
                         supervisor={"overrun_storm_count": 10**9})
    loop = ControlLoop(cfg, make_plant())
    seen = _record_threads(monkeypatch)
    with loop:
        loop.start()
        for om in (1000.0, 2500.0, 4000.0):
            loop.set_operating_point(om, 5.0)
            assert _wait(lambda om=om: loop.status()["last_frame"]["omega_rpm"] == om), \
                loop.status()["last_frame"]
        assert loop.fast.operating_point == (4000.0, 5.0)
    assert len(seen) == 3
    assert "rigd-loop" not in seen and set(seen) == {threading.current_thread().name}


def test_lockstep_change_applies_at_the_next_batch_boundary(monkeypatch, sim_config):
    seen = _record_threads(monkeypatch)
    with ControlLoop(sim_config, make_plant()) as loop:
        loop.run_cycles(100)
        loop.set_operating_point(3000.0, 6.0)
        res = loop.run_segment(np.zeros((10, 2)), record="memory")
    from rigd.frame import REC

    # the plant swaps the block in at its next step; the frame that step produces is the
    # next cycle's input: one cycle of latency, deterministic in lock-step
    om = res.frames[:, REC["omega_rpm"]]
    assert om[0] == 0.0 and np.all(om[1:] == 3000.0)
    assert set(seen) == {threading.current_thread().name}     # plant build + the change


def test_preparation_runs_just_below_the_loop_and_the_caller_is_restored(monkeypatch):
    """While the loop thread runs SCHED_FIFO, the caller prepares at the helpers' priority (an
    ordinary thread preempted while it holds the GIL stalls the loop thread: overruns)."""
    import os

    seen = []
    real = sim_params.ParamBlocks.__call__

    def build(*a, **k):
        seen.append((os.sched_getscheduler(0), os.sched_getparam(0).sched_priority))
        return real(*a, **k)

    cfg = default_config(clock={"mode": "realtime", "spin_us": 0.0, "priority": 50},
                         supervisor={"overrun_storm_count": 10**9})
    before = os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0)
    with ControlLoop(cfg, make_plant()) as loop:
        loop.start()
        monkeypatch.setattr(sim_params.ParamBlocks, "__call__", build)
        loop.set_operating_point(2000.0, 5.0)
        fifo = loop.rt.helper_priority is not None
    loop.set_operating_point(3000.0, 5.0)                # loop closed: not boosted
    if not fifo:
        import pytest

        pytest.skip(f"SCHED_FIFO not permitted here: {loop.rt_warnings}")
    assert seen == [(os.SCHED_FIFO, 49), (before[0], 0)]
    assert (os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0)) == before
