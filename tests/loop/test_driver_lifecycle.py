"""Driver lifecycle (rigd/driver.py): configure → activate → deactivate → cleanup, with
defaults that keep the two-method (open/close) interface of third-party drivers working."""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import numpy as np
from loop_helpers import make_plant

from rigd.driver import ACTIVE, INACTIVE, UNCONFIGURED, FastDriver
from rigd.loop.loop import ControlLoop


class OldStyleDriver(FastDriver):
    """A third-party driver written against the older interface: open/read/write/close only."""

    name = "oldstyle"

    def __init__(self, plant):
        super().__init__({}, fs=plant.fs)
        self.plant = plant
        self.log: list[tuple] = []

    def open(self):
        self.log.append(("open",))

    def read(self, frame_in):
        self.plant.read(frame_in)

    def write(self, drive):
        self.plant.write(drive)
        self.log.append(("write", drive.copy()))

    def close(self):
        self.log.append(("close",))


def test_old_style_driver_runs_and_gets_the_safe_drive_before_close(sim_config):
    drv = OldStyleDriver(make_plant())
    with ControlLoop(sim_config, drv) as loop:
        assert drv.lifecycle == ACTIVE and drv.log[0] == ("open",)
        loop.run_segment(np.full((200, 2), 0.5), record="memory")
    assert drv.lifecycle == UNCONFIGURED
    assert drv.log[-1] == ("close",)
    kind, last = drv.log[-2]
    c = sim_config.config
    safe = [min(max(v.kff * c.loop.r0_v, c.loop.drive_v[0]), c.loop.drive_v[1])
            for v in c.valves]
    assert kind == "write" and np.allclose(last, safe)
    assert [e[0] for e in drv.log].count("open") == 1 and drv.log.count(("close",)) == 1


def test_transitions_are_ordered_and_idempotent():
    drv = OldStyleDriver(make_plant())
    safe = np.full(4, 5.0)
    drv.deactivate(safe)                       # not active: nothing happens
    assert drv.lifecycle == UNCONFIGURED and drv.log == []
    drv.activate()                             # configures first
    assert drv.lifecycle == ACTIVE and drv.log == [("open",)]
    drv.activate()
    drv.deactivate(safe)
    drv.deactivate(safe)                       # once only
    assert drv.lifecycle == INACTIVE and [e[0] for e in drv.log] == ["open", "write"]
    drv.cleanup()
    drv.cleanup()
    assert drv.lifecycle == UNCONFIGURED and [e[0] for e in drv.log] == ["open", "write", "close"]


def test_serial_deactivate_holds_the_device_and_survives_writes(tmp_path):
    """Deactivated, the serial driver has told the front-end to hold its safe voltage and
    sends no drive, whatever is written; activated again, drives reach the valves."""
    from rigd_drivers.serial.driver import SerialFrameDriver

    # the emulator in a process of its own (tests/service/emuproc.py: as a thread of this
    # process it was starved on a loaded machine); its host timeout (60 s) cannot be what
    # makes it hold here
    sys.path.insert(0, str(Path(__file__).parents[1] / "service"))
    from emuproc import EmulatorProcess
    from faultkit import wait_for

    emu = EmulatorProcess(str(tmp_path / "frontend"), fs=5000.0, hold_timeout=60.0,
                          tx_buffer_s=0.5)
    drv = SerialFrameDriver({"port": emu.port, "backlog": 256, "timeout_ms": 50})
    frame = np.zeros(13)
    drive = np.array([9.0, 9.0, 1.0, 1.0])

    def exchange(seconds, until=None):
        end = time.monotonic() + seconds
        ev = threading.Event()
        while time.monotonic() < end and not (until is not None and until()):
            drv.read(frame)
            drv.write(drive)
            ev.wait(0.0005)

    try:
        drv.activate()
        exchange(10.0, until=lambda: not emu.holding and emu.drive_frames > 50)
        assert not emu.holding and np.allclose(emu.applied, drive)
        drv.deactivate(np.full(4, 5.0))
        exchange(0.2)                          # the loop would go on writing: ignored
        # the device processes frames in order: once it has read the hold (outputs disabled)
        # it holds, and stays so, as none of the writes above was sent (a sent drive frame
        # would follow the hold and enable the outputs again)
        assert wait_for(lambda: emu.holding and int(emu.last_drive[1]) & 1 == 0, 30.0)
        exchange(0.2)
        assert int(emu.last_drive[1]) & 1 == 0
        assert emu.holding and np.all(emu.applied == emu.hold_v)
        drv.activate()
        exchange(10.0, until=lambda: not emu.holding)
        assert not emu.holding and np.allclose(emu.applied, drive)
    finally:
        drv.cleanup()
        emu.stop()
