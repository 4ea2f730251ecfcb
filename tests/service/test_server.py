"""Control socket: protocol, server and client against a test double of the loop."""

import json
import os
import socket
import stat
import threading

import numpy as np
import pytest
from fakeloop import FakeLoop  # noqa: E402  (tests/service on sys.path via rootdir conftest)

from rigd.controller import Controller, to_wire
from rigd.errors import InputError
from rigd.service.client import ControlClient, ControlError
from rigd.service.protocol import Dispatcher, RequestError, parse_request
from rigd.service.server import RESERVED, ControlServer


@pytest.fixture()
def served(tmp_path):
    loop = FakeLoop()
    disp = Dispatcher(loop, info=lambda: {"pid": os.getpid()})
    srv = ControlServer(tmp_path / "rigd.sock", disp.handle_line, max_line=4096, max_clients=8,
                        evict_idle_s=None)     # the refusal at the door (eviction: below)
    with srv:
        yield srv, loop, disp


def _raw(path, data, n=1):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(5)
    s.connect(str(path))
    s.sendall(data)
    buf = b""
    while buf.count(b"\n") < n:
        chunk = s.recv(65536)
        if not chunk:
            break
        buf += chunk
    s.close()
    return [json.loads(x) for x in buf.splitlines()]


def test_commands_reach_the_loop(served):
    srv, loop, _ = served
    assert stat.S_IMODE(os.stat(srv.path).st_mode) == 0o660
    with ControlClient(srv.path) as c:
        assert c.call("ping")["pid"] == os.getpid()
        assert c.call("controller.enable") == {"enabled": True}
        assert c.call("operating_point.set", omega_rpm=3000, p_inj_bar=4.5)["omega_rpm"] == 3000
        st = c.call("status")
        assert st["controller_enabled"] is True and st["omega_rpm"] == 3000
        assert st["nan_field"] is None  # strict JSON on the wire
        assert c.call("timing")["compute_us"]["p99"] == 2.0
        loop.fault = 3
        assert c.call("faults")["faults"][0]["name"] == "sensor_nan"
        c.call("fault.reset")
        assert loop.fault == 0
        c.call("controller.load", path="/x/k.yaml", controller=to_wire(Controller(
            np.array([[0.5]]), np.zeros((1, 2)), np.zeros((2, 1)), np.zeros((2, 2)), 5000.0)))
    assert ("enable_controller", True) in loop.calls
    assert ("set_operating_point", 3000.0, 4.5) in loop.calls
    assert ("load_controller", "/x/k.yaml") in loop.calls


@pytest.mark.parametrize("line, needle", [
    (b"this is not json\n", "not JSON"),
    (b"[1, 2]\n", "JSON object"),
    (b'{"id": 1}\n', "no 'cmd'"),
    (b'{"id": 1, "cmd": "self_destruct"}\n', "unknown command"),
    (b'{"id": 1, "cmd": "ping", "extra": 1}\n', "unknown argument"),
    (b'{"id": 1, "cmd": "operating_point.set", "omega_rpm": "fast", "p_inj_bar": 4}\n',
     "omega_rpm"),
    (b'{"id": 1, "cmd": "operating_point.set", "omega_rpm": NaN, "p_inj_bar": 4}\n',
     "omega_rpm"),
    (b'{"id": 1, "cmd": "operating_point.set", "omega_rpm": -1, "p_inj_bar": 4}\n',
     "must be >= 0"),
    (b'{"id": 1, "cmd": "controller.load"}\n', "path"),
    (b'{"id": 1, "cmd": "controller.load", "path": "relative.yaml"}\n', "absolute"),
    # a path alone is never opened (the daemon reads no file a client names)
    (b'{"id": 1, "cmd": "controller.load", "path": "/etc/passwd"}\n', "content is missing"),
    (b'{"id": 1, "cmd": "operating_point.set", "omega_rpm": 13, "p_inj_bar": 4}\n',
     "internal error: RuntimeError: boom"),
    (b'{"id": 1, "cmd": "experiment.start", "path": "/x.yaml", "text": "kind: prbs"}\n',
     "not available"),
    (b'{"id": 1, "cmd": "experiment.start", "path": "/x.yaml"}\n', "content is missing"),
    (b"\xff\xfe\n", "not UTF-8"),
    (b"[" * 100000 + b"\n", "longer than"),
])
def test_malformed_requests_get_one_error_line(served, line, needle):
    srv, _, _ = served
    (reply,) = _raw(srv.path, line)
    assert reply["ok"] is False and needle in reply["error"]
    assert "\n" not in reply["error"]
    # and the server still answers
    with ControlClient(srv.path) as c:
        assert c.call("ping")["pong"] is True


def test_error_reply_keeps_id_and_client_error(served):
    srv, _, _ = served
    with ControlClient(srv.path) as c:
        r = c.request("operating_point.set", omega_rpm=1)
        assert r["ok"] is False and r["id"] == 1 and "p_inj_bar" in r["error"]
        with pytest.raises(ControlError, match="unknown command"):
            c.call("nope")


def test_pipelined_and_partial_lines(served):
    srv, _, _ = served
    reqs = b"".join(json.dumps({"id": i, "cmd": "ping"}).encode() + b"\n" for i in range(50))
    replies = _raw(srv.path, reqs, n=50)
    assert [r["id"] for r in replies] == list(range(50))
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(srv.path)
    s.settimeout(5)
    for b in b'{"id": "x", "cmd"': s.sendall(bytes([b]))  # noqa: E701
    s.sendall(b': "ping"}\n')
    assert json.loads(s.recv(4096))["id"] == "x"
    s.close()


def test_many_clients_and_a_silent_one(served):
    srv, loop, _ = served
    silent = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    silent.connect(srv.path)
    silent.sendall(b'{"id": 1, "cmd": "ping"')  # never finishes its line
    errors = []

    def worker(k):
        try:
            with ControlClient(srv.path, timeout=10) as c:
                for _ in range(40):
                    r = c.call("operating_point.set", omega_rpm=float(k), p_inj_bar=4.0)
                    assert r["omega_rpm"] == float(k)
        except Exception as exc:  # collected and asserted below
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    silent.close()
    assert errors == []
    assert sum(1 for c in loop.calls if c[0] == "set_operating_point") == 240


def test_client_limit(served):
    srv, _, _ = served
    socks = []
    for _ in range(8 + RESERVED):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.connect(srv.path)
        socks.append(s)
    with ControlClient(srv.path, timeout=5) as c:
        # the refusal comes on accept, unasked; the connection is closed right after it (a
        # request sent first raced that close: EPIPE on a loaded machine)
        r = c.read_reply()
    assert r["ok"] is False and "too many clients" in r["error"]
    for s in socks:
        s.close()


class _SafeFake(FakeLoop):
    def status(self):
        return {"fault": {"code": self.fault, "name": "operator_safe", "seq": 1, "text": ""}}


def test_a_full_daemon_keeps_a_slot_for_control_and_says_it_is_full(tmp_path):
    """Every slot taken: a reserved connection takes a control command (``safe``, a reset, a
    controller switch, ...) and no query, and the client says in one line that the daemon is
    full (it once said "reply id None does not match"). A nested line there is refused, and
    the server goes on serving (a RecursionError in its thread would have ended it)."""
    loop = _SafeFake()
    srv = ControlServer(tmp_path / "rigd.sock", Dispatcher(loop).handle_line, max_clients=8,
                        evict_idle_s=None)
    srv.start()
    socks = []
    for _ in range(8):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.connect(srv.path)
        socks.append(s)
    with ControlClient(srv.path, timeout=5) as c, \
            pytest.raises(InputError, match=r"refused the connection: too many clients \(max 8\)"
                                            r": the daemon is full; only control commands"):
        c.request("status")
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(5)
        s.connect(srv.path)
        s.sendall(b"[" * 60000 + b"\n")
        assert b"too many clients" in s.recv(4096)
    with ControlClient(srv.path, timeout=5) as c:
        assert c.call("controller.enable") == {"enabled": True}
    assert loop.enabled
    with ControlClient(srv.path, timeout=5) as c:
        assert c.call("safe")["safe"] is True
    assert loop.fault
    for s in socks:
        s.close()
    srv.stop()


def test_idle_clients_are_dropped(tmp_path):
    disp = Dispatcher(FakeLoop())
    with ControlServer(tmp_path / "rigd.sock", disp.handle_line, idle_s=0.2) as srv:
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.settimeout(30)
        s.connect(srv.path)
        assert s.recv(1) == b""                # closed by the daemon, not by us
        s.close()
        assert srv.stats["idle_closed"] == 1
        with ControlClient(srv.path, timeout=5) as c:   # an active client is served
            assert c.call("ping")["pong"] is True


def test_stale_socket_replaced_live_refused(tmp_path):
    path = tmp_path / "rigd.sock"
    dead = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    dead.bind(str(path))
    dead.close()  # file left behind, nobody listening
    disp = Dispatcher(FakeLoop())
    with ControlServer(path, disp.handle_line), \
            pytest.raises(InputError, match="another daemon"):
        ControlServer(path, disp.handle_line).start()
    assert not path.exists()
    path.write_text("not a socket")
    with pytest.raises(InputError, match="not a socket"):
        ControlServer(path, disp.handle_line).start()


def test_parse_request_unit():
    rid, cmd, args = parse_request(b'{"id": 5, "cmd": "experiment.start", "path": "/a.yaml"}')
    assert (rid, cmd, args.path) == (5, "experiment.start", "/a.yaml")
    with pytest.raises(RequestError, match="exactly one"):
        parse_request(b'{"cmd": "experiment.start"}')


def test_query_cache_bounded_and_invalidated_by_commands():
    import time as _t

    loop = FakeLoop()
    calls = []
    orig = loop.status
    loop.status = lambda: (calls.append(1), orig())[1]
    d = Dispatcher(loop, cache_s=10.0)
    for _ in range(50):
        d.handle_line(b'{"cmd": "status"}')
    assert len(calls) == 1  # a flood of queries costs the loop one status()
    d.handle_line(b'{"cmd": "controller.enable"}')
    r = json.loads(d.handle_line(b'{"cmd": "status"}'))
    assert len(calls) == 2 and r["result"]["controller_enabled"] is True
    d0 = Dispatcher(loop)  # no cache by default
    d0.handle_line(b'{"cmd": "status"}')
    d0.handle_line(b'{"cmd": "status"}')
    assert len(calls) == 4
    assert _t.monotonic() > 0


def test_deferred_replies_keep_order_and_do_not_hold_other_clients(tmp_path):
    """``handle`` may return a Future: the server serves others meanwhile, the waiting
    client's pipelined lines stay behind it, and a client gone before its reply is harmless."""
    from concurrent.futures import Future

    futures = []

    def handle(line):
        req = json.loads(line)
        if req["cmd"] == "slow":
            f = Future()
            futures.append((req["id"], f))
            return f
        return json.dumps({"id": req["id"], "ok": True}).encode() + b"\n"

    with ControlServer(tmp_path / "s.sock", handle) as srv:
        a = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        a.settimeout(10)
        a.connect(srv.path)
        a.sendall(b'{"id": 1, "cmd": "slow"}\n{"id": 2, "cmd": "fast"}\n')
        gone = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        gone.connect(srv.path)
        gone.sendall(b'{"id": 9, "cmd": "slow"}\n')
        gone.shutdown(socket.SHUT_WR)         # half-closed: still gets its reply
        other = _raw(srv.path, b'{"id": 3, "cmd": "fast"}\n')
        assert other == [{"id": 3, "ok": True}]          # served while 1 and 9 wait
        assert srv.stats["deferred"] == 2 and srv.stats["requests"] == 3  # 2 waits behind 1
        ids = dict(futures)
        ids[9].set_result(b'{"id": 9, "late": true}\n')
        gone.settimeout(10)
        assert json.loads(gone.recv(4096)) == {"id": 9, "late": True}
        assert gone.recv(4096) == b""                    # then closed by the server
        gone.close()
        ids[1].set_result(b'{"id": 1, "ok": true}\n')
        buf = b""
        while buf.count(b"\n") < 2:
            buf += a.recv(4096)
        assert [json.loads(x)["id"] for x in buf.splitlines()] == [1, 2]
        a.sendall(b'{"id": 4, "cmd": "slow"}\n')
        while len(futures) < 3:
            assert _raw(srv.path, b'{"id": 0, "cmd": "fast"}\n')[0]["ok"]
        a.close()                                        # gone before its reply
        futures[-1][1].set_result(b'{"id": 4}\n')        # delivered to nobody, no error
        assert _raw(srv.path, b'{"id": 5, "cmd": "fast"}\n') == [{"id": 5, "ok": True}]


def test_a_stopped_push_ends_the_client_stream_at_once(tmp_path):
    """A push that fails sends one error line (no id); ``ControlClient.stream`` raises it as a
    ControlError at once instead of skipping it and waiting for its time-out."""
    class Broken:
        next_due = 0.0

        def update(self, now):
            raise ValueError("Out of range float values are not JSON compliant")

    def handle(line):
        req = json.loads(line)
        ok = json.dumps({"id": req["id"], "ok": True, "result": {"fs_hz": 1.0}}).encode()
        return ok + b"\n", Broken()

    with ControlServer(tmp_path / "s.sock", handle) as srv:
        c = ControlClient(srv.path, timeout=60.0).connect()
        it = c.stream(rate_hz=50, points=8)
        assert c.subscribed == {"fs_hz": 1.0}
        with pytest.raises(ControlError, match="push stopped: internal error: ValueError"):
            next(it)
        c.close()


def test_idle_clients_make_room_for_a_new_one_busy_ones_do_not(tmp_path):
    """Every slot held by idle connections: a new client's query is served (not refused at
    the door) — the connection idle longest is closed with one line saying why; a client
    whose request is still being answered is never the one closed."""
    import time
    from concurrent.futures import Future

    pending: Future = Future()

    def handle(line):
        req = json.loads(line)
        if req["cmd"] == "slow":
            return pending
        return json.dumps({"id": req["id"], "ok": True, "result": {"pong": True}}).encode() \
            + b"\n"

    with ControlServer(tmp_path / "s.sock", handle, max_clients=3, evict_idle_s=0.05) as srv:
        busy = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        busy.settimeout(30)
        busy.connect(srv.path)
        busy.sendall(b'{"id": 1, "cmd": "slow"}\n')     # its answer is on its way
        idle = []
        for _ in range(2):
            idle.append(socket.socket(socket.AF_UNIX, socket.SOCK_STREAM))
            idle[-1].settimeout(30)
            idle[-1].connect(srv.path)
        while srv.stats["connections"] < 3 or srv.stats["requests"] < 1:
            time.sleep(0.01)
        time.sleep(0.1)                                   # all three silent for > 0.05 s
        with ControlClient(srv.path, timeout=30) as c1:   # one idle closed for it
            assert c1.call("ping") == {"pong": True}
            assert srv.stats["evicted_clients"] == 1
            closed = idle[0].recv(4096)                  # the idlest: the older idle one
            assert b"idle longest" in closed and b"max 3" in closed, closed
            time.sleep(0.1)
            with ControlClient(srv.path, timeout=30) as c2:   # and the next one for this one
                assert c2.call("ping") == {"pong": True}
            assert srv.stats["evicted_clients"] == 2
            assert b"idle longest" in idle[1].recv(4096)  # idle since before c1's answer
        pending.set_result(b'{"id": 1, "ok": true, "result": {}}\n')
        assert json.loads(busy.recv(4096))["id"] == 1   # the busy one was kept and answered
        for s in [busy, *idle]:
            s.close()
