"""A dead loop thread or a raising cycle: safe outputs at once, ``loop_died`` latched and shown,
the loop stopped; and objects handed to the loop are validated before they reach it."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from loop_helpers import make_plant

from rigd.controller import Controller
from rigd.driver import FastDriver
from rigd.errors import InputError
from rigd.loop import cycle as K
from rigd.loop import faults as FC
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import default_config


class WatchedDriver(FastDriver):
    """The simulated plant on the per-cycle path, keeping every drive written (in a
    preallocated array) and its lifecycle calls."""

    name = "watched"

    def __init__(self, plant, n=200_000):
        super().__init__({}, fs=plant.fs)
        self.plant = plant
        self.drives = np.full((n, 4), np.nan)
        self.n = 0
        self.calls: list[str] = []
        self.wrote = threading.Event()

    def read(self, frame_in):
        self.plant.read(frame_in)

    def write(self, drive):
        if self.n < len(self.drives):
            self.drives[self.n] = drive
        self.n += 1
        self.plant.write(drive)
        self.wrote.set()

    def on_deactivate(self, safe_drive):
        self.calls.append("deactivate")
        super().on_deactivate(safe_drive)

    def on_cleanup(self):
        self.calls.append("cleanup")


def _safe(cfg):
    """The documented safe drive: each valve's feed-forward at r_p = r0, clamped."""
    lo, hi = cfg.loop.drive_v
    return np.array([min(max(v.kff * cfg.loop.r0_v, lo), hi) for v in cfg.valves])


def _raising_cycle_after(monkeypatch, n_ok):
    real = K.rt_cycle
    count = [0]

    def rt_cycle(*args):
        count[0] += 1
        if count[0] > n_ok:
            raise FloatingPointError("injected: the cycle raised")
        real(*args)

    monkeypatch.setattr(K, "rt_cycle", rt_cycle)


def test_realtime_cycle_raises_outputs_safe_at_once_fault_latched_loop_stopped(monkeypatch):
    cfg = default_config(clock={"mode": "realtime", "spin_us": 0.0},
                         supervisor={"overrun_storm_count": 10**9})
    drv = WatchedDriver(make_plant())
    loop = ControlLoop(cfg, drv)
    _raising_cycle_after(monkeypatch, 500)
    with loop:
        loop.start()
        assert loop.wait(30.0), "the loop's death must stop it (wait returns)"
        n_at_death = drv.n
        st = loop.status()
        # the last write of the loop thread is the safe drive, right after the last cycle
        np.testing.assert_allclose(drv.drives[n_at_death - 1], _safe(cfg.config))
        assert drv.calls == ["deactivate"]
        assert st["fault"]["name"] == "loop_died" and st["fault"]["code"] == FC.LOOP_DIED
        assert not st["running"]
        assert "injected" in st["loop_error"]
        assert any(f["code"] == FC.LOOP_DIED and "injected" in f["text"] for f in loop.faults())
        with pytest.raises(RuntimeError, match="loop died"):
            loop.run_cycles(10)
    assert drv.calls == ["deactivate", "cleanup"]          # close: no second command
    assert drv.n == n_at_death


def test_lockstep_kernel_raise_makes_outputs_safe_and_latches(monkeypatch, sim_config):
    drv = WatchedDriver(make_plant())
    loop = ControlLoop(sim_config, drv)
    real, count = K.cycle, [0]

    def cycle(*args):
        count[0] += 1
        if count[0] > 300:
            raise ZeroDivisionError("injected")
        real(*args)

    with loop:
        loop.run_cycles(100)
        monkeypatch.setattr(K, "cycle", cycle)
        with pytest.raises(ZeroDivisionError):
            loop.run_cycles(1000)
        np.testing.assert_allclose(drv.drives[drv.n - 1], _safe(sim_config.config))
        assert loop.status()["fault"]["name"] == "loop_died"
        assert loop.stopped


def _ctrl(A, B, C, D, fs=5000.0):
    return Controller(np.asarray(A, float), np.asarray(B, float), np.asarray(C, float),
                      np.asarray(D, float), fs, "<test>")


@pytest.mark.parametrize("bad, what", [
    (lambda: _ctrl(np.eye(3) * 0.5, np.zeros((3, 2)), np.zeros((3, 3)), np.zeros((2, 2))),
     "C must be 2x3"),
    (lambda: _ctrl(np.eye(2) * 0.5, np.zeros((2, 3)), np.zeros((2, 2)), np.zeros((2, 2))),
     "B must be 2x2"),
    (lambda: _ctrl(np.eye(65) * 0.5, np.zeros((65, 2)), np.zeros((2, 65)), np.zeros((2, 2))),
     "order 65 is too high"),
    (lambda: _ctrl(np.eye(2) * 1.5, np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))),
     "unstable"),
    (lambda: _ctrl(np.eye(2) * np.nan, np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))),
     "NaN"),
    (lambda: _ctrl(np.eye(2) * 0.5, np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)),
                   fs=1000.0), "differs from the loop rate"),
])
def test_controller_objects_are_validated_before_they_reach_the_loop(sim_config, bad, what):
    with ControlLoop(sim_config, make_plant()) as loop:
        with pytest.raises(InputError, match=what):
            loop.load_controller(bad())
        assert not loop.commands.queue          # nothing was posted to the loop thread
        loop.run_cycles(50)
        assert loop.status()["fault"]["code"] == 0
    with pytest.raises(InputError, match=what):
        ControlLoop(sim_config, make_plant(), controller=bad())


def test_segment_inputs_are_validated_before_they_reach_the_loop(sim_config):
    with ControlLoop(sim_config, make_plant()) as loop:
        seq0 = loop.status()["seq"]
        with pytest.raises(InputError, match="not callable"):
            loop.run_segment(np.zeros((10, 2)), events=[(3, "impact")])
        with pytest.raises(InputError, match="NaN"):
            loop.run_segment(np.full((10, 2), np.nan))
        assert loop.status()["seq"] == seq0 and loop.player.current is None
