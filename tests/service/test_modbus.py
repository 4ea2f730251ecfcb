"""Modbus slow driver against a real pymodbus server on loopback, incl. stop and come back."""

import time

import numpy as np
import pytest
from modbus_server import NullModem, PlcServer, free_port

from rigd.configio import load_model
from rigd.errors import FaultError, InputError
from rigd.frame import IN_OMEGA, IN_P_INJ, N_IN
from rigd_drivers.modbus.driver import ModbusDriver, ModbusOptions, float_to_regs, regs_to_float


def _wait(pred, timeout=60.0):
    """True once ``pred()`` holds (``timeout`` only bounds a hang: a loaded machine is slow)."""
    t = time.monotonic() + timeout
    while time.monotonic() < t:
        if pred():
            return True
        time.sleep(0.01)
    return False


def test_float_words():
    for order in ("big", "little"):
        assert regs_to_float(float_to_regs(4.25, order), order) == 4.25
    assert float_to_regs(1.0, "big") == [0x3F80, 0]


def test_poll_setpoints_stop_and_come_back():
    plc = PlcServer(p_inj_bar=4.5, omega_rpm=2500.0).start()
    # the reply timeout is long (5 s, the most the driver allows): a poll that fails here
    # fails because the PLC is gone (a refused connection fails at once), never because a
    # busy machine delayed a loopback answer
    drv = ModbusDriver({"host": "127.0.0.1", "port": plc.port,
                        "timeout_s": 5.0, "reconnect_s": 0.1, "failures_to_fault": 2})
    drv.open()
    drv.poll_hz = 50.0
    drv.start_polling()
    try:
        assert _wait(lambda: drv.latest().ok)
        frame = np.zeros(N_IN)
        assert drv.fill(frame)
        assert frame[IN_P_INJ] == pytest.approx(4.5) and frame[IN_OMEGA] == 2500.0
        plc.values["omega_rpm"] = 4000.0
        assert _wait(lambda: drv.latest().omega_rpm == 4000.0)
        drv.write_setpoints(p_inj_bar=5.5, omega_rpm=3300.0)
        assert _wait(lambda: plc.setpoints == {"p_inj_bar": 5.5, "omega_rpm": 3300.0})
        # reading never blocks: while a poll waits for the PLC's answer (the PLC holds it),
        # fill() hands over the last values — it returns before that poll has ended
        plc.hold = True
        assert _wait(lambda: plc.waiting == 1)      # the polling thread is blocked in a read
        c = drv.counters()
        frame[:] = 0.0
        assert drv.fill(frame) and frame[IN_OMEGA] == 4000.0
        assert plc.waiting == 1 and drv.counters() == c, "fill() waited for the poll"
        plc.hold = False
        assert _wait(lambda: drv.counters()["polls"] > c["polls"])
        # the PLC dies: a fault after 2 failed polls, last values kept
        plc.stop()
        assert _wait(lambda: not drv.latest().ok)
        s = drv.latest()
        assert "modbus" in s.error and s.omega_rpm == 4000.0
        assert not drv.fill(frame) and frame[IN_OMEGA] == 4000.0
        assert drv.counters()["faults"] == 1
        # a device status word != 0 is a fault too
        plc2 = PlcServer(port=plc.port, p_inj_bar=6.0, omega_rpm=1000.0, status=0).start()
        assert _wait(lambda: drv.latest().ok and drv.latest().p_inj_bar == 6.0)
        assert drv.counters()["reconnects"] == 1
        plc2.values["status"] = 0x0004
        assert _wait(lambda: not drv.latest().ok)
        assert "0x0004" in drv.latest().error
        plc2.stop()
    finally:
        drv.close()


def test_rtu_over_a_serial_line_stop_and_come_back():
    """RTU: the driver on one end of a pseudo-terminal null-modem pair, a real pymodbus RTU
    server on the other; the PLC goes away (server stopped, line dead) and comes back.
    Parity 'N': a Linux pseudo-terminal refuses PARENB (EINVAL), real UARTs take 'E'."""
    line = NullModem()
    plc = PlcServer(device=line.b, p_inj_bar=4.5, omega_rpm=2500.0, parity="N").start()
    # a reply timeout that a busy machine does not reach by delaying an answer (1 s; at
    # 19200 baud a request and its answer take ~10 ms): only the dead line fails polls
    drv = ModbusDriver({"transport": "rtu", "device": line.a, "baudrate": 19200, "parity": "N",
                        "timeout_s": 1.0, "reconnect_s": 0.1, "failures_to_fault": 2})
    drv.open()
    drv.poll_hz = 50.0
    drv.start_polling()
    try:
        assert _wait(lambda: drv.latest().ok, 10), drv.latest()
        frame = np.zeros(N_IN)
        assert drv.fill(frame)
        assert frame[IN_P_INJ] == pytest.approx(4.5) and frame[IN_OMEGA] == 2500.0
        plc.values["omega_rpm"] = 4000.0
        assert _wait(lambda: drv.latest().omega_rpm == 4000.0)
        drv.write_setpoints(p_inj_bar=5.5, omega_rpm=3300.0)
        assert _wait(lambda: plc.setpoints == {"p_inj_bar": 5.5, "omega_rpm": 3300.0})
        assert plc.reads >= 2 and line.bytes > 50      # it really went over the serial line
        # the PLC goes away: fault after 2 failed polls (timeouts), last values kept
        line.unplug()
        plc.stop()
        assert _wait(lambda: not drv.latest().ok)
        s = drv.latest()
        assert "modbus" in s.error and line.a in s.error and s.omega_rpm == 4000.0
        assert drv.counters()["faults"] == 1
        # and comes back: values flow again, counted as one reconnection
        plc2 = PlcServer(device=line.b, p_inj_bar=6.0, omega_rpm=1000.0, parity="N").start()
        line.plug()
        assert _wait(lambda: drv.latest().ok and drv.latest().p_inj_bar == 6.0, 10), \
            drv.latest()
        assert drv.counters()["reconnects"] == 1 and drv.counters()["faults"] == 1
        plc2.stop()
    finally:
        drv.close()
        line.close()


def test_poll_raises_fault_when_nobody_listens():
    """``failures_to_fault`` (3) failed polls in a row are a fault, from the first poll on:
    the first two return no values (no fault yet), the third raises."""
    drv = ModbusDriver({"host": "127.0.0.1", "port": free_port(), "timeout_s": 0.1,
                        "reconnect_s": 0.01})
    assert drv.poll() == {} and drv.poll() == {}
    with pytest.raises(FaultError, match="modbus"):
        drv.poll()
    assert not drv.latest().ok and drv.counters()["errors"] == 3


def test_options_validation(tmp_path):
    p = tmp_path / "mb.yaml"
    p.write_text("transport: rtu\nbaudrate: 9600\n")
    with pytest.raises(InputError, match="needs 'device'"):
        load_model(p, ModbusOptions)
    p.write_text("transport: tcp\nhost: plc\nport: 70000\n")
    with pytest.raises(InputError, match=r"mb.yaml:3: port"):
        load_model(p, ModbusOptions)
    assert ModbusOptions(transport="rtu", device="/dev/ttyUSB0").parity == "E"


def test_shipped_rig_config_validates_with_these_drivers():
    """config/rig.yaml (written by the loop engineer) against the drivers' Options models."""
    from pathlib import Path

    from rigd.rigconfig import load_config
    from rigd_drivers.serial.driver import SerialFrameDriver, SerialFrameOptions

    lc = load_config(Path(__file__).resolve().parents[2] / "config" / "rig.yaml")
    cls, opts = lc.driver_options("fast")
    assert cls is SerialFrameDriver and isinstance(opts, SerialFrameOptions)
    scls, sopts = lc.driver_options("slow", 0)
    assert scls is ModbusDriver and isinstance(sopts, ModbusOptions)
    assert sopts.registers.omega == 2


def _loop_with_plc(tmp_path, plc, timeout_s, **supervisor):
    """A lock-step loop (simulated plant) whose slow driver is the Modbus driver on ``plc``."""
    from daemon_helpers import make_config

    from rigd.loop.app import build_drivers
    from rigd.loop.loop import ControlLoop
    from rigd.rigconfig import load_config

    lc = load_config(make_config(
        tmp_path, drivers={"fast": {"name": "sim"}, "slow": [{"name": "modbus", "poll_hz": 50.0,
                           "options": {"host": "127.0.0.1", "port": plc.port,
                                       "timeout_s": timeout_s, "reconnect_s": 0.05}}]},
        supervisor=supervisor))
    fast, slow, hz = build_drivers(lc)
    return ControlLoop(lc, fast, slow_drivers=slow, slow_poll_hz=hz, clock="lockstep")


def test_slow_first_answer_does_not_latch_stale(tmp_path):
    """The PLC answers its first read after 2 s (within the driver's 4 s timeout), then at
    once. The staleness clock (``slow_stale_s`` 1 s) starts at the first good poll: no
    ``slow_driver`` at start. (It started before the first poll and latched the fault at
    cycle 0 of a loop whose first poll — connect included — was slow.)"""
    from faultkit import wait_for

    plc = PlcServer(p_inj_bar=4.5, omega_rpm=0.0, first_delay_s=2.0).start()
    try:
        loop = _loop_with_plc(tmp_path, plc, timeout_s=4.0, slow_stale_s=1.0)
        with loop:
            # the slow first answer and nine more; the loop runs cycles meanwhile, so a
            # staleness request would be latched as it is posted
            assert wait_for(lambda: (loop.run_cycles(50), plc.reads >= 10)[1], 30.0)
            loop.run_cycles(100)
            assert [f["name"] for f in loop.faults()] == []
            assert loop.status()["fault"]["code"] == 0
            assert loop.slow[0].latest().ok and loop.slow[0].latest().p_inj_bar == 4.5
    finally:
        plc.stop()


def test_first_poll_bound_latches_slow_driver(tmp_path):
    """The first poll has its own bound (``slow_first_poll_s``): a first answer later than
    that latches ``slow_driver`` while the poll is still waiting (not only when it fails)."""
    from faultkit import wait_for

    from rigd.loop import faults as FC

    plc = PlcServer(p_inj_bar=4.5, omega_rpm=0.0, first_delay_s=4.5).start()
    try:
        loop = _loop_with_plc(tmp_path, plc, timeout_s=5.0, slow_first_poll_s=0.5)
        with loop:
            assert wait_for(lambda: (loop.run_cycles(50),
                                     loop.status()["fault"]["code"] == FC.SLOW_DRIVER)[1], 30.0)
            assert plc.reads == 0, "latched by the first-poll bound, not by an answer"
            assert loop.faults()[-1]["name"] == "slow_driver"
    finally:
        plc.stop()


def test_late_first_answer_is_no_fault(tmp_path):
    """The PLC answers the very first read only after the driver has given up on it (its
    timeout counted): one failed poll, not ``failures_to_fault`` (3), so no fault — the next
    polls answer. (The first failure latched ``slow_driver`` at cycle 0: before a good poll
    there was no grace.) The first answer waits for the driver's error count, an event, and
    the timeout (1 s) is long enough that no later loopback answer misses it on a busy
    machine: three failures in a row would take three seconds without an answer."""
    from faultkit import wait_for

    parts = {}
    plc = PlcServer(p_inj_bar=4.5, omega_rpm=0.0, first_until=lambda: "loop" in parts and
                    parts["loop"].slow[0].counters()["errors"] >= 1).start()
    try:
        loop = parts["loop"] = _loop_with_plc(tmp_path, plc, timeout_s=1.0)
        with loop:
            assert wait_for(lambda: (loop.run_cycles(50), plc.reads >= 10)[1], 120.0)
            loop.run_cycles(100)
            assert [f["name"] for f in loop.faults()] == []
            assert loop.slow[0].counters()["errors"] >= 1, "the first poll did time out"
            assert loop.slow[0].latest().ok and loop.slow[0].latest().p_inj_bar == 4.5
    finally:
        plc.stop()
