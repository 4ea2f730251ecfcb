"""Operating-point changes are prepared outside the loop thread and swapped in O(1).

The simulated plant's parameter block needs two matrix exponentials and allocations; before,
``ControlLoop`` called the driver's ``set_operating_point`` from the loop thread and built it
there. Now the caller's thread builds it and the loop thread only stages the prepared block.
"""

from __future__ import annotations

import threading

import numpy as np
from loop_helpers import make_plant

import rigd_drivers.sim_params as sim_params
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
