"""Waiting for the SAFE word's confirmation (rigd.service.safe_request): a word no loop takes
costs the requester (``rigd web``'s event loop, ``rigd ctl safe``) a few dozen looks, not one
every 0.5 ms for the whole timeout, and the wait ends at the timeout with the request still
pending; a word a loop takes is answered with the loop's confirmation."""

from __future__ import annotations

import asyncio
import threading
import time

from rigd.loop import faults as FC
from rigd.loop.safeword import W_ACK_CODE, W_ACK_N, W_ACK_SEQ, W_REQ, W_SEQ, SafeWord
from rigd.service.safe_request import FIRST_WAIT_S, MAX_WAIT_S, SafeWordClient, backoff

#: the timeout given when no loop takes the request, s
NOBODY_S = 0.5


def _word(tmp_path) -> tuple[SafeWord, str]:
    sock = str(tmp_path / "rigd.sock")
    owner = SafeWord()
    owner.attach_file(sock + ".safe")
    return owner, sock


class _Counting(SafeWordClient):
    """A client counting its looks at the confirmation."""

    looks = 0

    def ack(self, c0):
        self.looks += 1
        return super().ack(c0)


def test_the_waits_double_from_the_first_to_the_cap_and_stop_at_the_timeout():
    waits = []
    for w in backoff(0.4):
        waits.append(w)
        time.sleep(w)
    assert waits[0] == FIRST_WAIT_S
    assert all(0 < w <= MAX_WAIT_S for w in waits)
    # each wait doubles the last one up to the cap; only the last may be cut at the timeout
    for prev, w in zip(waits[:-2], waits[1:-1], strict=True):
        assert w == min(2 * prev, MAX_WAIT_S), waits
    assert waits[-1] <= min(2 * waits[-2], MAX_WAIT_S)
    assert list(backoff(0.0)) == [] and list(backoff(-1.0)) == []


def test_a_word_no_loop_takes_costs_a_few_looks_and_ends_at_the_timeout(tmp_path):
    owner, sock = _word(tmp_path)
    try:
        # at most the doubling part plus one look per MAX_WAIT_S of the rest (and the last
        # look after the timeout); the old 0.5 ms poll made ~1000 looks here
        most = 8 + NOBODY_S / MAX_WAIT_S + 2
        for run in ("async", "blocking"):
            client = _Counting(sock)
            t0 = time.monotonic()
            if run == "async":
                got = asyncio.run(client.safe_async(NOBODY_S))
            else:
                got = client.safe(NOBODY_S)
            assert got is None, run
            assert time.monotonic() - t0 >= NOBODY_S, run     # it waited the whole timeout
            assert 2 <= client.looks <= most, (run, client.looks)
            # the request stays pending for the next cycle that runs
            assert owner.word[W_REQ] != 0 and owner.word[W_ACK_N] == 0, run
            client.close()
    finally:
        owner.detach_file()


def _taker(owner: SafeWord, halt: threading.Event) -> threading.Thread:
    """A stand-in for the cycle: advances the cycle count and takes a new request value as
    the kernel does (acknowledges it at the cycle it runs)."""

    def run():
        seen = 0
        while not halt.is_set():
            w = owner.word
            w[W_SEQ] += 1
            if w[W_REQ] != seen:
                seen = int(w[W_REQ])
                w[W_ACK_CODE] = FC.OPERATOR_SAFE
                w[W_ACK_SEQ] = w[W_SEQ]
                w[W_ACK_N] += 1
            time.sleep(0.0002)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def test_a_word_a_loop_takes_is_confirmed(tmp_path):
    owner, sock = _word(tmp_path)
    halt = threading.Event()
    taker = _taker(owner, halt)
    try:
        for run in ("async", "blocking"):
            client = SafeWordClient(sock)
            a = (asyncio.run(client.safe_async(60.0)) if run == "async"
                 else client.safe(60.0))
            assert a is not None, run
            assert a["latched_at"] >= a["requested_at"] and a["via"] == "safe word", a
            assert a["fault"]["name"] == "operator_safe", a
            client.close()
        # a confirmation that comes late (the waits at their cap by then) is still seen
        halt.set()
        taker.join(5)
        halt.clear()
        owner.word[W_SEQ] += 1        # a cycle ran after the last request was taken
        client = SafeWordClient(sock)
        n0 = int(owner.word[W_ACK_N])

        async def late():
            task = asyncio.ensure_future(client.safe_async(60.0))
            await asyncio.sleep(0.3)
            assert not task.done()                # nothing takes the request yet
            _taker(owner, halt)                   # now a loop takes it
            return await task

        a = asyncio.run(late())
        assert a is not None and int(owner.word[W_ACK_N]) == n0 + 1, a
        client.close()
    finally:
        halt.set()
        owner.detach_file()
