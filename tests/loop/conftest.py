"""Fixtures for the loop tests (helpers live in loop_helpers.py)."""

import pytest

from rigd.rigconfig import default_config


@pytest.fixture
def sim_config():
    return default_config(clock={"mode": "lockstep"}, plant={"seed": 5},
                          recorder={"ring_frames": 1 << 16, "flush_interval_s": 0.1})

