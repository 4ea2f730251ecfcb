"""Operator-facing truth: after a fault, status says K∞ is off (as the recording's k_on does),
keeps the operator's request visible, and a reset clears it; `rigd ctl status` says so in
plain words (the daemon-process side is checked in test_faults_process.py)."""

import math

import numpy as np
from daemon_helpers import make_config
from faultkit import Injector, controller_file

from rigd.cli.ctl import status_summary
from rigd.frame import IN_E_X, REC
from rigd.loop.app import build_drivers
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import load_config


def test_status_controller_after_fault_reset_enable(tmp_path):
    lc = load_config(make_config(tmp_path, clock={"spin_us": 0.0}))
    fast, slow, hz = build_drivers(lc)

    def nan(frame):
        frame[IN_E_X] = math.nan
    inj = Injector(fast, nan)
    loop = ControlLoop(lc, inj, slow_drivers=slow, slow_poll_hz=hz,
                       controller=controller_file(tmp_path), clock="lockstep")
    with loop:
        loop.enable_controller(True)
        loop.run_cycles(600)
        c = loop.status()["controller"]
        assert c["enabled"] and c["requested"] and c["blend"] == 1.0
        assert "K∞: on" in status_summary(loop.status())
        inj.armed = True
        res = loop.run_segment(np.zeros((50, 2)), record="memory")
        st = loop.status()
        assert st["fault"]["name"] == "sensor_nan"
        assert res.frames[-1, REC["k_on"]] == 0                 # the recording says off ...
        assert st["controller"]["enabled"] is False              # ... and so does status
        assert st["controller"]["requested"] is True and st["controller"]["blend"] == 0.0
        text = status_summary(st)
        assert "FAULT sensor_nan" in text and "K∞: OFF: tripped by the fault" in text
        inj.armed = False
        loop.reset_fault()
        loop.run_cycles(10)
        c = loop.status()["controller"]
        assert loop.status()["fault"]["code"] == 0
        assert c["enabled"] is False and c["requested"] is False  # a reset leaves K∞ off
        assert "K∞: off" in status_summary(loop.status())
        loop.enable_controller(True)
        loop.run_cycles(600)
        c = loop.status()["controller"]
        assert c["enabled"] and c["requested"] and c["blend"] == 1.0
