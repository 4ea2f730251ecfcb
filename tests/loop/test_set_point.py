"""``status()["set_point"]``: what ``set_operating_point`` last *applied* (the web console's
operating-point form shows it). Queued is not applied; dropped is never applied."""

from __future__ import annotations

from loop_helpers import InjectingDriver, make_plant

from rigd.loop.loop import ControlLoop
from rigd.rigconfig import default_config


def _loop(driver=None):
    cfg = default_config(clock={"mode": "lockstep"})
    return ControlLoop(cfg, driver if driver is not None else make_plant(omega_rpm=1000.0,
                                                                          p_inj_bar=4.5))


def test_the_configured_point_then_an_op_once_the_loop_applied_it():
    loop = _loop()
    with loop:
        assert loop.status()["set_point"] == {"omega_rpm": 1000.0, "p_inj_bar": 4.5,
                                              "source": "config"}
        t = loop.set_operating_point(2500.0, 5.0)
        # queued, not applied: still the old set-point
        assert loop.status()["set_point"]["omega_rpm"] == 1000.0
        loop.run_cycles(1)
        assert loop.applied(t)
        assert loop.status()["set_point"] == {"omega_rpm": 2500.0, "p_inj_bar": 5.0,
                                              "source": "op"}


def test_an_op_overtaken_by_safe_never_becomes_the_set_point():
    loop = _loop()
    with loop:
        loop.run_cycles(1)
        gen = loop.safe_generation
        loop.request_safe()
        loop.run_cycles(2)                          # the SAFE is taken: generation moves on
        t = loop.set_operating_point(3000.0, 6.0, gen=gen)
        loop.run_cycles(2)
        assert t.dropped and not t.applied
        assert loop.status()["set_point"]["omega_rpm"] == 1000.0
        loop.reset_fault()
        t = loop.set_operating_point(1500.0, 5.5)
        loop.run_cycles(2)
        assert loop.applied(t)
        assert loop.status()["set_point"]["omega_rpm"] == 1500.0


def test_a_driver_without_a_prepared_swap_counts_the_set_point_at_once():
    plant = make_plant()
    loop = _loop(InjectingDriver(plant))            # no operating_point, no prepared swap
    with loop:
        assert loop.status()["set_point"] is None   # nothing known before the first op
        assert loop.set_operating_point(2000.0, 5.0) is None
        assert loop.status()["set_point"] == {"omega_rpm": 2000.0, "p_inj_bar": 5.0,
                                              "source": "op"}
