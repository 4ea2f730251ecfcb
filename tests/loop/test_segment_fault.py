"""A segment played with ``stop_on_fault`` ends at the cycle a fault is latched in.

Before, a segment always played to its planned end (in the safe state after a fault), so an
experiment stayed "running" for the rest of its record after ``safe`` or any latched fault.
The loop thread only flags the segment (O(1)); the caller finishes it and closes the record
after the fault's cycle. Both clocks, a compiled lock-step batch and the per-cycle path.
"""

from __future__ import annotations

import numpy as np
import pytest
from loop_helpers import InjectingDriver, make_plant

from rigd.frame import REC
from rigd.loop import faults as FC
from rigd.loop.loop import ControlLoop
from rigd.recording.h5sink import open_recording
from rigd.rigconfig import default_config

N = 20_000          # 4 s at 5 kHz: far longer than it takes to see the fault
AT = 500            # the trip is posted just before this cycle of the segment


def _loop(clock, per_cycle=False):
    cfg = default_config(clock={"mode": clock, "spin_us": 0.0},
                         supervisor={"overrun_storm_count": 10**9},
                         recorder={"ring_frames": 1 << 16, "flush_interval_s": 0.1})
    plant = make_plant()
    return ControlLoop(cfg, InjectingDriver(plant) if per_cycle else plant)


def _exc(n=N):
    return 0.2 * np.sign(np.random.default_rng(1).standard_normal((n, 2)))


@pytest.mark.parametrize("clock, per_cycle", [("lockstep", False), ("lockstep", True),
                                              ("realtime", False)],
                         ids=["lockstep-batch", "lockstep-per-cycle", "realtime"])
def test_segment_ends_at_the_fault_cycle_and_its_record_is_closed(tmp_path, clock, per_cycle):
    path = tmp_path / "seg.h5"
    with _loop(clock, per_cycle) as loop:
        loop.run_cycles(200)
        res = loop.run_segment(_exc(), record=str(path), stop_on_fault=True,
                               events=[(AT, lambda: loop.trip(FC.OPERATOR_SAFE))])
        latched = loop.status()["fault"]
        assert loop.running or clock == "lockstep"      # the loop lives on, in the safe state
    assert latched["name"] == "operator_safe"
    assert res.fault is not None and res.fault["name"] == "operator_safe"
    assert res.fault["seq"] == latched["seq"] == res.last_seq   # ended at the latching cycle
    assert AT <= res.n_frames <= AT + 2 < N
    assert [f["name"] for f in res.faults] == ["operator_safe"]
    with open_recording(path) as f:
        fr = f["frames"][:]
    assert len(fr) == res.n_frames                      # closed, nothing lost before the fault
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1) and fr[-1, REC["seq"]] == res.last_seq
    assert fr[-1, REC["fault"]] == FC.OPERATOR_SAFE and np.all(fr[:-1, REC["fault"]] == 0)
    assert np.any(fr[:-1, REC["x_x"]] != 0)             # the excitation was playing


def test_without_stop_on_fault_the_segment_plays_to_its_end(tmp_path, sim_config):
    with ControlLoop(sim_config, make_plant()) as loop:
        res = loop.run_segment(_exc(3000), record="memory",
                               events=[(AT, lambda: loop.trip(FC.OPERATOR_SAFE))])
    assert res.fault is None and res.n_frames == 3000
    assert [f["name"] for f in res.faults] == ["operator_safe"]


@pytest.mark.parametrize("clock", ["lockstep", "realtime"])
def test_a_fault_latched_before_ends_the_segment_at_its_first_cycle(clock):
    with _loop(clock) as loop:
        loop.run_cycles(100)
        loop.trip(FC.OPERATOR_STOP)
        loop.run_segment(np.zeros((10, 2)))              # the trip is taken
        first = loop.status()["fault"]
        res = loop.run_segment(_exc(), record="memory", stop_on_fault=True)
    assert first["name"] == "operator_stop"
    assert res.n_frames == 1 and res.fault["name"] == "operator_stop"
    assert res.fault["seq"] == first["seq"] < res.first_seq and res.faults == []
