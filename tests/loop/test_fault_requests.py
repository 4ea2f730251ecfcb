"""Fault requests are a single-writer path: a request posted at any moment is never lost.

Before, five writers shared one slot (``st[S_EXT_FAULT]``) that the kernel read and then
cleared; a write between the read and the clear vanished (lock-step batches run without the
GIL, so that window is real). Now each source owns a request counter and the kernel owns the
acknowledged counter (rigd/loop/requests.py).
"""

from __future__ import annotations

import threading

import numpy as np
from loop_helpers import make_plant

from rigd.loop import cycle as K
from rigd.loop import faults as FC
from rigd.loop import layout as L
from rigd.loop import requests as RQ
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import default_config


def test_requests_are_counters_the_kernel_acknowledges_never_clears():
    st = np.zeros(L.N_ST)
    req = RQ.FaultRequests(st)
    assert K.take_requests(st) == 0
    req.post(RQ.SLOW, FC.SLOW_DRIVER)
    req.post(RQ.OPERATOR, FC.OPERATOR_STOP)
    assert req.pending()
    code = K.take_requests(st)
    assert code in (FC.SLOW_DRIVER, FC.OPERATOR_STOP)
    assert not req.pending()
    # the writers' slots are untouched by the reader: counters and codes are still there
    assert req.posted(RQ.SLOW) == 1 and req.posted(RQ.OPERATOR) == 1
    assert st[L.S_FREQ + 3 * RQ.SLOW + 1] == FC.SLOW_DRIVER
    # a request posted right after the kernel looked is seen by the next look
    req.post_from_loop(FC.OVERRUN_STORM)
    assert K.take_requests(st) == FC.OVERRUN_STORM
    assert K.take_requests(st) == 0


def test_concurrent_requests_during_nogil_batches_are_all_seen():
    """Three sources post at the same instant while the lock-step thread runs compiled batches
    without the GIL; every round must end with every request acknowledged, one fault latched
    per round and every request listed (never a round where a request vanished)."""
    cfg = default_config(clock={"mode": "lockstep", "batch_cycles": 32},
                         recorder={"ring_frames": 1 << 14})
    loop = ControlLoop(cfg, make_plant())
    sources = [(RQ.OPERATOR, FC.OPERATOR_STOP), (RQ.RECORDER, FC.RECORDER_OVERFLOW),
               (RQ.SLOW, FC.SLOW_DRIVER)]
    rounds = 150
    barrier = threading.Barrier(len(sources) + 1)
    errors: list[BaseException] = []

    def producer(src, code):
        try:
            for _ in range(rounds):
                barrier.wait(30)
                loop.requests.post(src, code)
                barrier.wait(30)
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)
            barrier.abort()

    def settled(pred, timeout=10.0):
        ev = threading.Event()
        for _ in range(int(timeout / 0.001)):
            if pred():
                return True
            ev.wait(0.001)
        return pred()

    with loop:
        loop.start()
        threads = [threading.Thread(target=producer, args=sc) for sc in sources]
        for t in threads:
            t.start()
        for _ in range(rounds):
            loop.reset_fault()
            # the reset has been taken by the loop (the kernel runs after it) and is done
            assert settled(lambda: not loop.commands.queue and
                           loop.status()["fault"]["code"] == 0)
            barrier.wait(30)          # all producers post now
            barrier.wait(30)          # all have posted
            assert settled(lambda: not loop.requests.pending()), "a request was never seen"
            assert loop.status()["fault"]["code"] in {c for _, c in sources}
        for t in threads:
            t.join(30)
        assert not errors, errors
        for src, _ in sources:
            assert loop.requests.posted(src) == rounds
            assert loop.requests.acknowledged(src) == rounds
        # every request is in the fault list: the one that latched and, beside it, the
        # others of the round (a fault of another kind while one is latched is listed too)
        faults = loop.faults()
        assert len(faults) == len(sources) * rounds
        for name in ("operator_stop", "recorder_overflow", "slow_driver"):
            assert sum(f["name"] == name for f in faults) == rounds
