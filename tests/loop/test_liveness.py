"""Liveness rules of the real-time cycle (rigd/loop/liveness.py, docs/loop.md "Liveness"):
bounds derived from the plant, the stall and lost-control-time rules in the kernel, the
watchdog's latch through the SAFE word, the miss fraction counting skipped periods."""

import threading
import time

import numpy as np
import pytest

from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop import liveness
from rigd.loop import safeword as SW
from rigd.loop.cycle import take_safe, watch_cycle
from rigd.loop.timing import miss_fraction
from rigd.rigconfig import SupervisorConfig

FS = 5000.0
PERIOD = 200_000  # ns


class _Plant:
    def __init__(self, tau):
        self.tau = tau

    def plant_time_constant_s(self):
        return self.tau


def _kernel(stall_s=0.018, window_s=0.18, lost_s=0.018):
    prm, st = np.zeros(L.N_PRM), np.zeros(L.N_ST)
    b = liveness.LivenessBounds(0.018, "config", stall_s, window_s, lost_s)
    liveness.fill(prm, b, FS)
    st[L.S_SEQ] = prm[L.P_GRACE_N]                 # past the start-up grace
    return prm, st, SW.SafeWord().word


def _run(prm, st, w, wakes):
    for t in wakes:
        watch_cycle(prm, st, w, int(t))
        take_safe(w, st)
        st[L.S_SEQ] += 1


def test_bounds_derive_from_the_plant_time_constant():
    sup = SupervisorConfig()
    b = liveness.derive(sup, _Plant(0.0181))
    assert (b.tau_s, b.tau_source) == (0.0181, "driver")
    assert b.stall_s == 0.0181 and b.storm_lost_s == 0.0181
    assert b.storm_window_s == pytest.approx(10 * 0.0181)
    b = liveness.derive(SupervisorConfig(plant_tau_s=0.05, stall_s=0.2), _Plant(0.0181))
    assert (b.tau_s, b.tau_source, b.stall_s, b.storm_lost_s) == (0.05, "config", 0.2, 0.2)
    b = liveness.derive(sup, object())
    assert (b.tau_s, b.tau_source) == (liveness.DEFAULT_TAU_S, "default")


def test_sim_plant_time_constant_is_the_fastest_bearing_envelope():
    from rigd_drivers.plant.physics import bearing_modes
    from rigd_drivers.sim.driver import SimPlantDriver

    tau = SimPlantDriver().plant_time_constant_s()
    f, z = bearing_modes(6000.0, 3.0)
    assert tau == pytest.approx(float(np.min(1 / (z * 2 * np.pi * f))))
    assert 0.017 < tau < 0.019


def test_one_gap_beyond_the_stall_bound_latches_loop_stall_with_its_length():
    prm, st, w = _kernel()
    t = 10**12
    wakes = [t + k * PERIOD for k in range(100)]
    _run(prm, st, w, wakes)                          # on time: nothing
    assert st[L.S_FAULT] == 0
    gap = 17_000_000                                  # 17 ms < 18 ms: held, no fault
    _run(prm, st, w, [wakes[-1] + gap])
    assert st[L.S_FAULT] == 0
    _run(prm, st, w, [wakes[-1] + gap + 19_000_000])  # 19 ms > 18 ms
    assert st[L.S_FAULT] == FC.LOOP_STALL
    assert w[SW.W_LOOP_GAP_NS] == 19_000_000
    assert w[SW.W_FAULT] == FC.LOOP_STALL            # mirrored for other processes
    assert "stood still for 0.019 s" in SW.stall_text(w)


def test_jitter_of_a_busy_machine_does_not_trip_but_lost_control_does():
    """Every other cycle 100 µs late with a 2 ms hiccup every second: updates are late, never
    absent for long — no fault. Four cycles on time, then 1.2 ms without a cycle, over and
    over (absent 40 % of the time): the bucket exceeds one stall bound within the plant's
    memory — overrun_storm."""
    prm, st, w = _kernel()
    rng = np.random.default_rng(1)
    t, wakes = 10**12, []
    for k in range(50_000):                            # 10 s
        late = 100_000 if k % 2 else 0
        if k % 5000 == 0:
            late += 2_000_000
        wakes.append(t + k * PERIOD + late + int(rng.integers(0, 20_000)))
    _run(prm, st, w, wakes)
    assert st[L.S_FAULT] == 0, st[L.S_LOST_NS]
    t, wakes = wakes[-1], []
    for g in range(1, 500):
        base = t + g * 2_000_000
        wakes += [base + k * PERIOD for k in range(4)]
    _run(prm, st, w, wakes)
    assert st[L.S_FAULT] == FC.OVERRUN_STORM


def test_the_start_up_transient_is_not_measured():
    prm, st, w = _kernel()
    assert prm[L.P_GRACE_N] == round(liveness.GRACE_S * FS)
    st[L.S_SEQ] = 0
    t = 10**12
    _run(prm, st, w, [t, t + 50_000_000])             # a 50 ms first cycle
    assert st[L.S_FAULT] == 0 and st[L.S_LOST_NS] == 0
    st[L.S_SEQ] = prm[L.P_GRACE_N]
    _run(prm, st, w, [t + 100_000_000])
    assert st[L.S_FAULT] == FC.LOOP_STALL


def test_the_former_count_rule_replaces_the_lost_time_rule_when_configured():
    b = liveness.derive(SupervisorConfig(overrun_storm_count=50), _Plant(0.0181))
    assert b.storm_lost_s == 0.0 and b.stall_s == 0.0181


def test_a_watchdog_request_latches_at_the_next_cycle():
    prm, st, w = _kernel(stall_s=0.0)                 # the kernel's own check off
    _run(prm, st, w, [10**12 + k * PERIOD for k in range(10)])
    w[SW.W_STALL_REQ] = SW.fresh_value()
    assert st[L.S_FAULT] == 0
    _run(prm, st, w, [10**12 + 11 * PERIOD])
    assert st[L.S_FAULT] == FC.LOOP_STALL
    assert st[L.S_FAULT_SEQ] == prm[L.P_GRACE_N] + 10


def test_the_watchdog_process_logic_latches_while_the_loop_stands():
    """rigd.service.watchdog.watch on a word whose cycle time stops moving."""
    import multiprocessing

    from rigd.service.watchdog import watch

    w = SW.SafeWord().word
    w[SW.W_STALL_BOUND_NS] = 50_000_000               # 50 ms
    here, there = multiprocessing.Pipe(duplex=False)
    stop = threading.Event()

    def loop():                                       # a loop stamping its cycles, then not
        while not stop.is_set():
            w[SW.W_CYCLE_NS] = time.monotonic_ns()
            w[SW.W_SEQ] += 1
            time.sleep(0.001)

    t = threading.Thread(target=loop, daemon=True)
    t.start()
    wd = threading.Thread(target=watch, args=(w, here), daemon=True)
    wd.start()
    try:
        time.sleep(0.2)
        assert w[SW.W_STALL_REQ] == 0, "no stall while it cycles"
        stop.set()
        t.join()
        stood_at = int(w[SW.W_SEQ])
        end = time.monotonic() + 30
        while w[SW.W_STALL_REQ] == 0 and time.monotonic() < end:
            time.sleep(0.01)
        assert w[SW.W_STALL_REQ] != 0
        assert w[SW.W_STALL_FROM] == stood_at
        lv = SW.live(w)
        assert lv["stalled"] and lv["age_s"] > 0.05
        stop.clear()
        t = threading.Thread(target=loop, daemon=True)
        t.start()
        end = time.monotonic() + 30
        while SW.live(w)["stalled"] and time.monotonic() < end:
            time.sleep(0.01)
        assert not SW.live(w)["stalled"]
    finally:
        stop.set()
        there.close()                                 # EOF: the watchdog returns
        wd.join(10)
    assert not wd.is_alive()


def test_miss_fraction_counts_skipped_periods():
    # 13581 cycles, one late cycle, then 3 s stopped: 15000 periods skipped
    assert miss_fraction(1, 15000, 13581) == pytest.approx(15001 / 28581)
    assert miss_fraction(1, 0, 13581) == pytest.approx(1 / 13581)
    assert miss_fraction(0, 0, 0) == 0.0
