"""``status`` and ``ping`` overlay the SAFE word on a snapshot that can be older
(rigd.service.liveview): a snapshot from before the loop's first cycle — still held by the
socket process when READY=1 went out, under load — does not make a cycling loop look stopped;
a loop that stopped or died does."""

import time

from rigd.loop import safeword as SW
from rigd.service import liveview


def _word(seq, stall_bound_ns=1_000_000_000):
    w = SW.SafeWord().word
    w[SW.W_STALL_BOUND_NS] = stall_bound_ns
    w[SW.W_SEQ] = seq
    w[SW.W_CYCLE_NS] = time.monotonic_ns()
    return w


def test_a_snapshot_from_before_the_first_cycle_does_not_stop_a_cycling_loop():
    before = {"running": False, "seq": 0, "fs_hz": 5000.0}
    w = _word(seq=120)
    assert liveview.not_cycling(before, w) is None
    assert liveview.status(before, w)["running"] is True


def test_a_loop_that_stopped_or_died_is_not_running():
    w = _word(seq=500)
    stopped = {"running": False, "seq": 500, "fs_hz": 5000.0}
    assert "not running (stopped)" in liveview.not_cycling(stopped, w)
    assert liveview.status(stopped, w)["running"] is False
    died = {"running": False, "seq": 400, "loop_error": "ZeroDivisionError()", "fs_hz": 5000.0}
    assert "ZeroDivisionError" in liveview.not_cycling(died, w)
    assert liveview.status(died, w)["running"] is False


def test_a_word_that_stands_still_is_a_stall_not_a_start():
    before = {"running": False, "seq": 0, "fs_hz": 5000.0}
    w = _word(seq=120, stall_bound_ns=50_000_000)
    w[SW.W_CYCLE_NS] = time.monotonic_ns() - 200_000_000          # 0.2 s ago, bound 50 ms
    assert "not cycling" in liveview.not_cycling(before, w)
    assert liveview.status(before, w)["running"] is False
