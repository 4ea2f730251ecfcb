"""The socket process's request handler (rigd.service.frontend.SnapshotHandler) in-process,
with a real multiprocessing pipe and a thread playing the daemon's command side: queries from
the snapshot, only valid commands forwarded, a flood of valid commands throttled."""

import json
import multiprocessing
import threading
import time
from concurrent.futures import Future

from rigd.service.frontend import SnapshotHandler

SNAP = {"status": {"seq": 7, "x": float("nan")}, "timing": {"cycles": 9},
        "faults": [{"code": 1}], "experiment": None, "info": {"pid": 1}}


def _daemon_side(conn, seen):
    while True:
        try:
            kind, tag, line, _ = conn.recv()
        except (EOFError, OSError, TypeError):  # TypeError: closed under it
            return
        seen.append(line)
        req = json.loads(line)
        reply = json.dumps({"id": req.get("id"), "ok": True, "result": {"ran": req["cmd"]}})
        conn.send(("reply", tag, reply.encode() + b"\n", dict(SNAP, v=1000 + len(seen))))


def _handler(rate=50.0):
    here, there = multiprocessing.Pipe()
    seen = []
    threading.Thread(target=_daemon_side, args=(there, seen), daemon=True).start()
    h = SnapshotHandler(here, clients=lambda: 3, max_commands_per_s=rate)
    h.install(dict(SNAP, v=1))
    return h, seen, here


def _ask(h, obj):
    r = h.handle_line(json.dumps(obj).encode())
    if isinstance(r, Future):     # a forwarded command: its reply comes from the daemon side
        r = r.result(30)
    return json.loads(r)


def test_queries_from_snapshot_and_bad_requests_never_forwarded():
    h, seen, conn = _handler()
    try:
        assert _ask(h, {"id": 1, "cmd": "status"}) == {"id": 1, "ok": True,
                                                       "result": {"seq": 7, "x": None}}
        assert _ask(h, {"id": "a", "cmd": "faults"})["result"] == {"faults": [{"code": 1}]}
        r = _ask(h, {"id": 2, "cmd": "experiment.status"})
        assert r["ok"] is False and "not available" in r["error"]
        p = _ask(h, {"cmd": "ping"})["result"]
        assert p["pong"] and p["pid"] == 1 and p["clients"] == 3 and p["socket_pid"]
        for bad in (b"nope", b'{"cmd": "reboot"}', b'{"cmd": "controller.load", "path": "k"}',
                    b'{"cmd": "operating_point.set", "omega_rpm": 1e9, "p_inj_bar": 1}'):
            assert json.loads(h.handle_line(bad))["ok"] is False
        assert seen == []                       # none of it reached the daemon side
        # an older snapshot never replaces a newer one
        h.install(dict(SNAP, v=0, status={"seq": 1}))
        assert _ask(h, {"cmd": "status"})["result"]["seq"] == 7
        r = _ask(h, {"id": 5, "cmd": "controller.enable"})
        assert r == {"id": 5, "ok": True, "result": {"ran": "controller.enable"}}
        assert len(seen) == 1
    finally:
        conn.close()


def test_flood_of_valid_commands_is_throttled():
    h, seen, conn = _handler(rate=20.0)
    try:
        t0 = time.monotonic()
        replies = [_ask(h, {"id": i, "cmd": "fault.reset"}) for i in range(200)]
        elapsed = time.monotonic() - t0
        ok = [r for r in replies if r["ok"]]
        refused = [r for r in replies if not r["ok"]]
        # the burst (20) plus what the rate refilled meanwhile, and no more
        assert 20 <= len(ok) <= 20 + 20.0 * elapsed + 1, (len(ok), elapsed)
        assert len(refused) > 100 and len(ok) == len(seen) == h.forwarded
        assert all("too many commands" in r["error"] for r in refused)
        assert refused[0]["id"] is not None
    finally:
        conn.close()


def _mute_daemon(conn, seen, hangup):
    """A daemon side that takes commands and never answers them; closes its end on ``hangup``
    (itself: a close from another thread would not end its blocked recv)."""
    while not hangup.is_set():
        try:
            if conn.poll(0.02):
                seen.append(conn.recv()[2])
        except (EOFError, OSError):
            return
    conn.close()


def _mute_handler(**kw):
    here, there = multiprocessing.Pipe()
    seen, hangup = [], threading.Event()
    threading.Thread(target=_mute_daemon, args=(there, seen, hangup), daemon=True).start()
    h = SnapshotHandler(here, **kw)
    h.install(dict(SNAP, v=1))
    return h, here, seen, hangup


def test_forwarded_commands_limited_and_timed_out():
    h, conn, seen, hangup = _mute_handler(max_in_flight=2, timeout_s=0.5)
    try:
        f1 = h.handle_line(b'{"id": 1, "cmd": "fault.reset"}')
        f2 = h.handle_line(b'{"id": 2, "cmd": "controller.enable"}')
        assert isinstance(f1, Future) and isinstance(f2, Future)
        r = json.loads(h.handle_line(b'{"id": 3, "cmd": "controller.disable"}'))
        assert r["id"] == 3 and "2 commands are already waiting" in r["error"]
        # queries are answered at once meanwhile
        assert _ask(h, {"id": 4, "cmd": "status"})["ok"] is True
        # no answer from the daemon: an error reply after timeout_s, then room again
        r1 = json.loads(f1.result(30))
        assert r1["id"] == 1 and "did not answer the command by its deadline" in r1["error"]
        assert "will never be applied" in r1["error"]
        assert json.loads(f2.result(30))["ok"] is False and h.in_flight == 0
        assert len(seen) == 2
    finally:
        hangup.set()
        h.close()
        conn.close()


def test_waiting_commands_fail_when_the_daemon_goes_away():
    h, conn, seen, hangup = _mute_handler()
    try:
        f5 = h.handle_line(b'{"id": 5, "cmd": "fault.reset"}')
        assert isinstance(f5, Future) and h.in_flight == 1
        hangup.set()                        # the daemon's end closes: waiting commands fail
        r5 = json.loads(f5.result(30))
        assert r5["id"] == 5 and "command channel is closed" in r5["error"]
        r6 = json.loads(h.handle_line(b'{"id": 6, "cmd": "fault.reset"}'))
        assert "command channel is closed" in r6["error"]
    finally:
        h.close()
        conn.close()


def test_safe_gets_through_when_the_rate_and_waiting_limits_refuse_commands():
    """The safety button: neither the token bucket nor the waiting-commands bound refuse it."""
    h, conn, seen, hangup = _mute_handler(max_in_flight=2, max_commands_per_s=2.0,
                                          timeout_s=30.0)
    try:
        futures = [h.handle_line(b'{"id": 1, "cmd": "fault.reset"}'),
                   h.handle_line(b'{"id": 2, "cmd": "controller.enable"}')]
        assert all(isinstance(f, Future) for f in futures)
        refused = json.loads(h.handle_line(b'{"id": 3, "cmd": "controller.disable"}'))
        assert refused["ok"] is False                    # out of tokens and of room
        for i in range(4, 8):
            f = h.handle_line(b'{"id": %d, "cmd": "safe"}' % i)
            assert isinstance(f, Future), f              # forwarded, not refused
        _wait_for(lambda: len(seen) == 6)
        assert [json.loads(x)["cmd"] for x in seen[2:]] == ["safe"] * 4
    finally:
        hangup.set()
        h.close()
        conn.close()


def _wait_for(cond, timeout=30.0):
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)
