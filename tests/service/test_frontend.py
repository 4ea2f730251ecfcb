"""The socket process's request handler (rigd.service.frontend.SnapshotHandler) in-process,
with a real multiprocessing pipe and a thread playing the daemon's command side: queries from
the snapshot, only valid commands forwarded, a flood of valid commands throttled."""

import json
import multiprocessing
import threading
import time

from rigd.service.frontend import SnapshotHandler

SNAP = {"status": {"seq": 7, "x": float("nan")}, "timing": {"cycles": 9},
        "faults": [{"code": 1}], "experiment": None, "info": {"pid": 1}}


def _daemon_side(conn, seen):
    while True:
        try:
            kind, tag, line, _ = conn.recv()
        except (EOFError, OSError):
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
    return json.loads(h.handle_line(json.dumps(obj).encode()))


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
