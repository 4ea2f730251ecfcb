"""A slow command does not stall the socket: queries are answered while a forwarded command is
pending in the daemon — alone, and while 20 clients hammer the socket and forward commands
too. The real parts: the daemon side (rigd.service.bridge.SocketFrontend) spawning the real
socket process (rigd.service.frontend) on a real Unix socket; behind it a test double of the
loop whose ``controller.load`` blocks until the test lets it finish (fakeloop.GatedLoop).

No timed asserts: "pending" is a fact here (the command is blocked inside the loop double
until the gate opens), so every query answered before the gate opens was answered while the
slow command was in progress. Latency figures: ``python -m bench socket_load``
(``socket_busy_status_ms``)."""

import json
import select
import socket
import threading

import pytest
from fakeloop import GatedLoop, controller_beside, gated_frontend

from rigd.service.client import controller_args


@pytest.fixture()
def busy(tmp_path):
    loop = GatedLoop()
    path = str(tmp_path / "rigd.sock")
    with gated_frontend(loop, path):
        yield path, loop


class Conn:
    def __init__(self, path):
        self.s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.s.settimeout(20)
        self.s.connect(path)
        self.buf = b""

    def send(self, obj):
        self.s.sendall(json.dumps(obj).encode() + b"\n")

    def has_reply(self):
        return b"\n" in self.buf or bool(select.select([self.s], [], [], 0)[0])

    def reply(self):
        while b"\n" not in self.buf:
            chunk = self.s.recv(65536)
            assert chunk, "connection closed"
            self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        return json.loads(line)

    def ask(self, obj):
        self.send(obj)
        return self.reply()

    def close(self):
        self.s.close()


def _start_slow_load(path, loop):
    a = Conn(path)
    a.send({"id": "load", "cmd": "controller.load", **controller_args(controller_beside(path))})
    assert loop.entered.wait(30), "the load did not reach the loop"
    return a


def test_status_answered_while_a_slow_load_is_pending(busy):
    path, loop = busy
    a = _start_slow_load(path, loop)
    c = Conn(path)
    c.send({"id": "op", "cmd": "operating_point.set", "omega_rpm": 1200, "p_inj_bar": 4.0})
    b = Conn(path)
    for i in range(20):
        r = b.ask({"id": i, "cmd": "status"})
        assert r["id"] == i and r["ok"] is True and r["result"]["running"] is True
    for q in ("timing", "faults"):
        assert b.ask({"id": q, "cmd": q})["ok"] is True
    ping = b.ask({"id": "p", "cmd": "ping"})["result"]
    assert ping["commands_waiting"] == 2          # the load and the op change behind it
    bad = b.ask({"id": "x", "cmd": "controller.load", "path": "relative.yaml"})
    assert bad["ok"] is False and "absolute" in bad["error"]
    # all of it answered while the load is still blocked in the loop
    assert not loop.gate.is_set() and not a.has_reply() and not c.has_reply()
    assert ("set_operating_point", 1200.0, 4.0) not in loop.calls   # queued behind the load
    loop.gate.set()
    assert a.reply() == {"id": "load", "ok": True, "result": {"loaded": controller_beside(path)}}
    assert c.reply()["result"] == {"omega_rpm": 1200.0, "p_inj_bar": 4.0}
    # and the next status reflects both commands (the reply carries a fresh snapshot)
    st = b.ask({"id": "s", "cmd": "status"})["result"]
    assert st["omega_rpm"] == 1200.0
    for x in (a, b, c):
        x.close()


def test_queries_answered_during_a_hammer_that_forwards_commands(busy):
    path, loop = busy
    a = _start_slow_load(path, loop)
    n_clients, n_queries = 20, 25
    errors: list[str] = []
    answered = [0] * n_clients
    cmd_conns = [Conn(path) for _ in range(n_clients)]
    queried = threading.Barrier(n_clients + 1)

    def client(k):
        try:
            c = cmd_conns[k]
            # two commands pipelined: the first waits behind the slow load, the second
            # behind the first (replies stay in request order)
            c.send({"id": f"{k}-op", "cmd": "operating_point.set", "omega_rpm": 100.0 + k,
                    "p_inj_bar": 4.0})
            c.send({"id": f"{k}-en", "cmd": "controller.enable"})
            q = Conn(path)
            for i in range(n_queries):
                cmd = ("status", "timing", "faults", "ping")[i % 4]
                r = q.ask({"id": i, "cmd": cmd})
                if not (r["ok"] is True and r["id"] == i):
                    errors.append(f"client {k}: {r}")
                answered[k] += 1
                if i % 5 == 0:   # a malformed request now and then: refused, not forwarded
                    r = q.ask({"id": "bad", "cmd": "operating_point.set", "omega_rpm": "x"})
                    if r["ok"] is not False:
                        errors.append(f"client {k}: bad request accepted: {r}")
            q.close()
        except Exception as exc:  # noqa: BLE001 - collected and asserted below
            errors.append(f"client {k}: {exc!r}")
        finally:
            queried.wait(60)

    threads = [threading.Thread(target=client, args=(k,)) for k in range(n_clients)]
    for t in threads:
        t.start()
    queried.wait(120)      # every client has had all its queries answered...
    assert errors == []
    assert answered == [n_queries] * n_clients
    # ...while the load was still blocked and every forwarded command still waiting
    assert not loop.gate.is_set() and not a.has_reply()
    assert not any(c.has_reply() for c in cmd_conns)
    probe = Conn(path)
    assert probe.ask({"cmd": "ping"})["result"]["commands_waiting"] == 1 + n_clients
    loop.gate.set()
    assert a.reply()["ok"] is True
    for k, c in enumerate(cmd_conns):
        r1, r2 = c.reply(), c.reply()
        assert r1 == {"id": f"{k}-op", "ok": True,
                      "result": {"omega_rpm": 100.0 + k, "p_inj_bar": 4.0}}
        assert r2 == {"id": f"{k}-en", "ok": True, "result": {"enabled": True}}
        c.close()
    for t in threads:
        t.join(30)
    ops = [c for c in loop.calls if c[0] == "set_operating_point"]
    assert len(ops) == n_clients and loop.calls[0] == ("load_controller", controller_beside(path))
    assert probe.ask({"cmd": "ping"})["result"]["commands_waiting"] == 0
    probe.close()
    a.close()
