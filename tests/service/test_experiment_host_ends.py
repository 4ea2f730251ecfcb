"""The experiment's state always ends (``complete``, ``interrupted`` or ``failed`` with the
reason), whatever its process does; a SAFE seen late stops only an experiment started before
it. :class:`~rigd.service.experiment_host.ExperimentHost` with stand-in experiment processes
(experiment_children.py) on a stand-in loop; the daemon's side: test_experiment_child_killed.py.
"""

import os
import signal
import time
from types import SimpleNamespace

import pytest
from daemon_helpers import PROCESS_S

from rigd.errors import InputError
from rigd.service.experiment_host import ExperimentHost

#: a request the stand-ins take (the real process would validate it)
SPEC = {"kind": "prbs"}


def _host(tmp_path, child, safe_generation=0):
    loop = SimpleNamespace(fs=5000.0, safe_generation=safe_generation, status=lambda: {})
    host = ExperimentHost(loop, tmp_path)
    host.entry = ("experiment_children", child)
    return loop, host


def _wait_running(host):
    end = time.monotonic() + PROCESS_S
    while host.status()["state"] == "starting":
        assert time.monotonic() < end, host.status()
        time.sleep(0.02)
    assert host.status()["state"] == "running", host.status()


def test_a_late_safe_stop_leaves_an_experiment_started_after_that_safe(tmp_path):
    # SAFE number 1 was taken and reset; the daemon's service thread, late, stops for it
    # only after a new experiment started: that one runs on to its end
    loop, host = _host(tmp_path, "runs_until_stopped", safe_generation=1)
    host.start(spec={**SPEC, "wait_s": 1.0})
    _wait_running(host)
    assert host.stop(before_safe=1) == {"stopping": False}
    host.join(PROCESS_S)
    assert host.status()["state"] == "complete", host.status()
    # a SAFE taken while it runs (number 2) stops it
    host.start(spec={**SPEC, "wait_s": None})
    _wait_running(host)
    loop.safe_generation = 2
    assert host.stop(before_safe=2) == {"stopping": True}
    host.join(PROCESS_S)
    assert host.status()["state"] == "interrupted", host.status()
    # and a plain stop (experiment.stop, SIGTERM) stops whatever runs
    host.start(spec={**SPEC, "wait_s": None})
    _wait_running(host)
    assert host.stop() == {"stopping": True}
    host.join(PROCESS_S)
    assert host.status()["state"] == "interrupted", host.status()


def test_a_process_that_never_says_a_word_is_killed_and_failed(tmp_path):
    _, host = _host(tmp_path, "silent")
    host.start_limit_s = 2.0
    t0 = time.monotonic()
    with pytest.raises(InputError, match="said nothing within 2 s of its start; killed"):
        host.start(spec=SPEC)
    st = host.status()
    assert st["state"] == "failed" and "killed" in st["message"], st
    assert time.monotonic() - t0 < PROCESS_S
    with pytest.raises(ProcessLookupError):
        os.kill(st["pid"], 0)                       # gone, and reaped
    host.entry = ("experiment_children", "runs_until_stopped")   # the host takes the next
    host.start(spec={**SPEC, "wait_s": 0.1})
    host.join(PROCESS_S)
    assert host.status()["state"] == "complete", host.status()


def test_a_process_that_ends_without_a_word_is_failed_with_how(tmp_path):
    _, host = _host(tmp_path, "exits")
    with pytest.raises(InputError, match=r"ended without its result \(exit status 3\)"):
        host.start(spec=SPEC)
    assert host.status()["state"] == "failed"


def test_a_process_killed_while_running_is_failed_with_the_signal(tmp_path):
    _, host = _host(tmp_path, "runs_until_stopped")
    host.start(spec={**SPEC, "wait_s": None})
    _wait_running(host)
    os.kill(host.pid, signal.SIGKILL)
    host.join(PROCESS_S)
    st = host.status()
    assert st["state"] == "failed" and "killed by SIGKILL" in st["message"], st
