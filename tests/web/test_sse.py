"""``GET /api/stream`` relays the daemon's ``stream.subscribe`` pushes as Server-Sent Events
(payload unchanged) and ends with one error event when the daemon refuses or goes away.
The daemon side here is a real Unix socket speaking the documented protocol."""

import json
import socket
import threading

import pytest
from starlette.testclient import TestClient
from webkit import TOKEN, auth
from webproc import sse_events

from rigd.web.app import Settings, build_app
from rigd.web.sse import stream_body


class PushServer:
    """Answers ``stream.subscribe`` (or refuses it) and pushes ``frames``, then closes."""

    def __init__(self, path, frames, refuse=None, then=None):
        self.srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.srv.bind(str(path))
        self.srv.listen(4)
        self.path, self.frames, self.refuse, self.then = str(path), frames, refuse, then
        self.requests = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        conn, _ = self.srv.accept()
        with conn:
            req = json.loads(conn.makefile("rb").readline())
            self.requests.append(req)
            if self.refuse:
                conn.sendall((json.dumps({"id": req["id"], "ok": False, "error": self.refuse})
                              + "\n").encode())
                return
            conn.sendall((json.dumps({"id": req["id"], "ok": True, "result": {
                "fs_hz": 5000.0, "rate_hz": req["rate_hz"], "points": req["points"],
                "channels": ["e_x", "e_y"]}}) + "\n").encode())
            for i, f in enumerate(self.frames):    # both separator styles of json.dumps
                sep = (",", ":") if i % 2 else (", ", ": ")
                conn.sendall((json.dumps({"stream": f}, separators=sep) + "\n").encode())
            if self.then is not None:
                conn.sendall((json.dumps(self.then) + "\n").encode())
                conn.makefile("rb").readline()          # hold the connection open

    def close(self):
        self.thread.join(10)
        self.srv.close()


def _events(client, url="/api/stream"):
    with client.stream("GET", url) as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        return list(sse_events(r.iter_lines()))


def _settings(tmp_path, sock):
    return Settings(socket=str(sock), runs_dir=tmp_path, config_dir=tmp_path, token=TOKEN)


def test_stream_payloads_are_relayed_unchanged(tmp_path):
    frames = [{"seq": 100 * i, "t_s": i * 0.02, "wall_ns": 10**18 + i, "n": 100, "dropped": 0,
               "min": {"e_x": [i - 1.0], "e_y": [0.5]}, "max": {"e_x": [i + 1.0], "e_y": [0.7]},
               "status": {"seq": 100 * i, "k_on": i % 2 == 1}} for i in range(5)]
    srv = PushServer(tmp_path / "d.sock", frames)
    with TestClient(build_app(_settings(tmp_path, srv.path)), headers=auth()) as client:
        events = _events(client, "/api/stream?rate_hz=25&points=100&channels=e_x,e_y")
    srv.close()
    assert srv.requests == [{"id": 1, "cmd": "stream.subscribe", "rate_hz": 25.0,
                             "points": 100, "channels": ["e_x", "e_y"]}]
    assert events[0] == ("subscribed", {"fs_hz": 5000.0, "rate_hz": 25.0, "points": 100,
                                        "channels": ["e_x", "e_y"]})
    assert [e for _, e in events[1:6]] == frames and all(n is None for n, _ in events[1:6])
    assert events[6][0] == "error" and "closed" in events[6][1]["error"]


def test_a_stopped_push_is_one_error_event_not_a_silent_stream(tmp_path):
    """The socket process stops a failed push with an error line without id: the relay ends
    the stream with one error event naming it (it once skipped it and sent keepalives)."""
    frames = [{"seq": 1, "n": 1, "min": {"e_x": [0.0]}, "max": {"e_x": [1.0]}}]
    stop = {"id": None, "ok": False, "error": "push stopped: internal error: ValueError: x"}
    srv = PushServer(tmp_path / "d.sock", frames, then=stop)
    with TestClient(build_app(_settings(tmp_path, srv.path)), headers=auth()) as client:
        events = _events(client)
    srv.close()
    assert [e for _, e in events[1:2]] == frames
    assert events[2:] == [("error", {"error": "daemon stopped the stream: push stopped: "
                                              "internal error: ValueError: x"})]


def test_stream_body_slices_only_pushed_lines():
    line = json.dumps({"stream": {"a": [1, {"b": 2}]}}, separators=(",", ":")).encode()
    assert json.loads(stream_body(line + b"\n")) == {"a": [1, {"b": 2}]}
    assert stream_body(b'{"id":1,"ok":true}\n') is None
    assert stream_body(b'{"stream":1}\n') is None


@pytest.mark.parametrize("refuse", ["unknown command 'stream.subscribe' (known: ping, ...)"])
def test_refused_subscription_is_one_error_event(tmp_path, refuse):
    srv = PushServer(tmp_path / "d.sock", [], refuse=refuse)
    with TestClient(build_app(_settings(tmp_path, srv.path)), headers=auth()) as client:
        events = _events(client)
    srv.close()
    assert events == [("error", {"error": f"daemon stream unavailable: {refuse}"})]


def test_no_daemon_is_one_error_event(tmp_path):
    app = build_app(_settings(tmp_path, tmp_path / "none.sock"))
    with TestClient(app, headers=auth()) as client:
        events = _events(client)
    assert len(events) == 1 and events[0][0] == "error"
    assert "daemon not reachable" in events[0][1]["error"] and "none.sock" in events[0][1]["error"]


def test_bad_stream_query_is_400(tmp_path):
    app = build_app(_settings(tmp_path, tmp_path / "none.sock"))
    with TestClient(app, headers=auth()) as client:
        r = client.get("/api/stream?rate_hz=fast")
    assert r.status_code == 400 and "bad query" in r.json()["error"]


class FloodServer:
    """Answers every ``stream.subscribe`` and pushes lines as fast as it can until the client
    closes; counts the connections still open."""

    def __init__(self, path):
        self.srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.srv.bind(str(path))
        self.srv.listen(64)
        self.open = 0
        self.accepted = 0
        self.conns = []
        self.lock = threading.Lock()
        self.all_closed = threading.Event()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        while True:
            try:
                conn, _ = self.srv.accept()
            except OSError:
                return
            with self.lock:
                self.open += 1
                self.accepted += 1
                self.conns.append(conn)
                self.all_closed.clear()
            threading.Thread(target=self._push, args=(conn,), daemon=True).start()

    def _push(self, conn):
        line = (json.dumps({"stream": {"seq": 1, "t": [0.0] * 50}}) + "\n").encode()
        try:
            req = json.loads(conn.makefile("rb").readline())
            conn.sendall((json.dumps({"id": req["id"], "ok": True, "result": {}})
                          + "\n").encode())
            while True:
                conn.sendall(line)
        except (OSError, ValueError):
            pass
        finally:
            conn.close()
            with self.lock:
                self.open -= 1
                if not self.open:
                    self.all_closed.set()

    def close(self):
        """Stop listening and end every connection still open from this side."""
        self.srv.close()
        with self.lock:
            for c in self.conns:
                try:
                    c.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass


def test_the_last_browser_leaving_closes_the_daemon_subscription(tmp_path):
    """Browsers come and go on a stream whose lines are always ready: each time the last one
    leaves, the daemon connection closes (a cancellation swallowed by ``asyncio.wait_for``
    left the subscription running for ever, one daemon slot per leak)."""
    import asyncio

    from rigd.web.sse import StreamHub

    srv = FloodServer(tmp_path / "d.sock")
    sub = {"rate_hz": 50.0, "points": 200, "channels": None}

    async def come_and_go(rounds: int) -> int:
        hub = StreamHub(str(tmp_path / "d.sock"), 30.0, 16)
        for _ in range(rounds):
            gens = []
            for _ in range(3):
                lease, key = hub.acquire(sub)
                gens.append(hub.events(lease, key, sub))
            for g in gens:                       # each browser reads a few events
                for _ in range(3):
                    await g.__anext__()
            for g in gens:                       # and leaves
                await g.aclose()
            assert not hub.feeds and hub.active == 0
        # every subscription closed by the daemon's count (a hang bound, not a timing)
        for _ in range(3000):
            if srv.all_closed.is_set():
                break
            await asyncio.sleep(0.01)
        leaked = srv.open
        srv.close()                              # the daemon ends the leaked ones itself
        return leaked

    try:
        leaked = asyncio.run(come_and_go(40))
        assert srv.accepted == 40
        assert leaked == 0, f"{leaked} of 40 subscriptions still open with no browser"
    finally:
        srv.close()
