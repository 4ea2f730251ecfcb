"""The daemon's stop (SIGTERM/SIGINT/``stop``): the safe state runs and is recorded for
``SAFE_CYCLES_ON_STOP`` cycles before the loop stops, however slowly the loop cycles."""

import argparse
import time

import numpy as np
from daemon_helpers import make_config
from faultkit import Injector, read_frames

from rigd.frame import REC
from rigd.loop import faults as FC
from rigd.loop.app import build_drivers
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import load_config
from rigd.service.daemon import SAFE_CYCLES_ON_STOP, Daemon


def test_stop_records_the_safe_state_on_a_slow_loop(tmp_path):
    """Every write of the fast driver takes 2 ms (ten 5 kHz periods), as on a loaded machine:
    the loop runs at most 500 cycles/s. The stop waited a fixed 4 ms (20 periods) of wall
    time, in which such a loop runs two or three cycles; it now counts the cycles."""
    lc = load_config(make_config(tmp_path, clock={"spin_us": 0.0}))
    fast, slow, hz = build_drivers(lc)
    inj = Injector(fast, lambda frame: time.sleep(0.002))
    inj.armed = True
    loop = ControlLoop(lc, inj, slow_drivers=slow, slow_poll_hz=hz, clock="realtime")
    rec = tmp_path / "stop.h5"
    daemon = Daemon(loop, lc, argparse.Namespace(no_notify=True))
    with loop:
        sink = loop.start_recording(rec)
        loop.start()
        assert loop.wait_cycles(50, timeout=60.0) >= 50
        daemon.shutdown("test")
        assert loop.wait(0.0), "the loop was told to stop"
        loop.stop_recording(sink)
    fr = read_frames(rec)
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1)
    safe = np.flatnonzero(fr[:, REC["fault"]] == FC.OPERATOR_STOP)
    assert safe.size >= SAFE_CYCLES_ON_STOP - 2, f"{safe.size} safe frames recorded"
    assert np.all(fr[safe[0]:, REC["fault"]] == FC.OPERATOR_STOP)
    assert np.all(fr[safe[0] + 1:, REC["k_on"]] == 0)
