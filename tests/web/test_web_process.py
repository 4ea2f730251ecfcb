"""``rigd web`` as a real process against a real daemon (``rigd run``, simulated rig): the
HTTP API mirrors ``rigd ctl``, the token guards it, paths stay inside, the stream is relayed."""

import http.client
from urllib.parse import urlsplit

import httpx2 as httpx
import pytest
from webproc import daemon_and_web, hang_report, sse_events, wait_for

#: hang bound of the experiment's ~1 s run, s: a slow spawn on a loaded 2-core machine takes tens
#: of seconds; below pytest-timeout (600 s), so that a hang reports where it stood
EXPERIMENT_HANG_S = 240.0


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("webrig")
    with daemon_and_web(tmp) as (d, web), \
            httpx.Client(base_url=web.url, timeout=60, headers=web.auth()) as http:
        yield d, web, http
    # uvicorn re-raises SIGTERM after its clean shutdown: -15 is a clean stop
    assert web.proc.returncode in (0, -15), web.lines


def _auth(web):
    return web.auth()


def _keys(obj, prefix=""):
    if isinstance(obj, dict):
        out = set()
        for k, v in obj.items():
            out |= {prefix + k} | _keys(v, prefix + k + ".")
        return out
    return set()


def test_status_is_ctl_status_json(rig):
    d, _, http = rig
    a = d.ctl_json("status")
    r = http.get("/api/status")
    c = d.ctl_json("status")
    assert r.status_code == 200
    b = r.json()
    assert _keys(b) == _keys(a) == _keys(c)
    assert a["seq"] <= b["seq"] <= c["seq"]
    for k in ("running", "clock", "fs_hz", "controller", "fault"):
        if k != "controller":
            assert b[k] == c[k], k
    assert b["controller"]["source"] == c["controller"]["source"]


def test_commands_mirror_rigd_ctl(rig):
    d, web, http = rig
    h = _auth(web)
    assert http.post("/api/enable", headers=h).status_code == 200
    wait_for(lambda: d.ctl_json("status")["controller"]["enabled"], what="K∞ enabled")
    assert http.post("/api/disable", headers=h).status_code == 200
    wait_for(lambda: not d.ctl_json("status")["controller"]["requested"], what="K∞ disabled")
    r = http.post("/api/op", json={"omega_rpm": 1500, "p_inj_bar": 4.5}, headers=h)
    assert r.status_code == 200 and r.json() == {"omega_rpm": 1500.0, "p_inj_bar": 4.5}
    wait_for(lambda: d.ctl_json("status")["last_frame"]["omega_rpm"] == 1500.0, what="Ω")
    r = http.post("/api/load", json={"path": "config/controller-k.yaml"}, headers=h)
    assert r.status_code == 200, r.text
    assert d.ctl_json("status")["controller"]["source"].endswith("controller-k.yaml")
    r = http.post("/api/load", json={"upload": {"name": "k.yaml", "text": "A: [[1.5]]\n"}},
                  headers=h)
    # not a controller: refused by the console's read of it (400), in the loader's one line
    assert r.status_code == 400 and "\n" not in r.json()["error"]
    assert d.ctl_json("status")["controller"]["source"].endswith("controller-k.yaml")
    r = http.post("/api/safe", headers=h)
    assert r.status_code == 200, r.text
    st = d.ctl_json("status")
    assert st["fault"]["name"] == "operator_safe" and not st["controller"]["enabled"]
    assert http.post("/api/reset", headers=h).status_code == 200
    wait_for(lambda: d.ctl_json("status")["fault"]["code"] == 0, what="fault reset")
    r = http.post("/api/start", json={"path": "config/experiments/web-short.yaml"}, headers=h)
    assert r.status_code == 200, r.text
    last: dict = {}

    def _over() -> bool:
        last.update(http.get("/api/experiment").json())
        return last["state"] in ("complete", "interrupted", "failed")   # every end state

    # a hang bound only, below pytest-timeout's: on a timeout the failure says where the
    # experiment stood (web's and daemon's view, the daemon's processes and threads)
    wait_for(_over, timeout=EXPERIMENT_HANG_S, interval=0.3,
             what=lambda: f"experiment finished (last /api/experiment: {last})\n"
                          + hang_report(d))
    exp = http.get("/api/experiment").json()
    assert exp["state"] == "complete", exp
    assert exp == d.ctl_json("experiment")
    assert http.post("/api/stop", headers=h).json() == {"stopping": False}
    runs = http.get("/api/runs").json()
    [run] = [x for x in runs if x.get("experiment") == "web-short"]
    assert run["kind"] == "prbs" and run["status"] == "complete" and run["source"] == "simulated"
    assert run["records"], run
    v = http.get(f"/api/runs/{run['name']}/{run['records'][0]}?points=300&channels=e_x").json()
    assert v["n"] >= 3000 and len(v["t_s"]) == 300 and v["decimated"]


def test_without_the_token_401_and_nothing_changes(rig):
    d, web, http = rig
    assert not d.ctl_json("status")["controller"]["requested"]
    before = d.ctl_json("status")["last_frame"]["omega_rpm"]
    for name, body in [("enable", {}), ("op", {"omega_rpm": 3333, "p_inj_bar": 4}),
                       ("safe", {})]:
        r = httpx.post(f"{web.url}/api/{name}", json=body, timeout=60)
        assert r.status_code == 401, name
        r = http.post(f"/api/{name}", json=body, headers={"Authorization": "Bearer nope"})
        assert r.status_code == 401, name
        r = http.post(f"/api/{name}", json=body, headers=web.auth(read=True))
        assert r.status_code == 403 and "read-only" in r.json()["error"], name
    st = d.ctl_json("status")
    assert not st["controller"]["requested"] and st["fault"]["code"] == 0
    assert st["last_frame"]["omega_rpm"] == before


@pytest.mark.parametrize("raw", [
    "/runs/../web-token", "/runs/%2e%2e/web-token", "/runs/..%2fweb-token",
    "/runs/%2E%2E%2Fweb-token", "/runs//etc/passwd", "/runs/%2fetc%2fpasswd",
    "/api/runs/../web-token", "/static/../../../../etc/passwd", "/static/..%2f..%2fapp.py",
    "/runs/.%2e/web-token",
])
def test_raw_paths_never_leave_the_folders(rig, raw):
    _, web, _ = rig
    u = urlsplit(web.url)
    conn = http.client.HTTPConnection(u.hostname, u.port, timeout=30)
    conn.request("GET", raw, headers=web.auth())   # http.client sends the path as is
    resp = conn.getresponse()
    body = resp.read().decode("utf-8", "replace")
    conn.close()
    assert resp.status in (400, 404), (raw, resp.status)
    assert web.token not in body and "root:" not in body and "def " not in body


def test_stream_relayed_from_the_daemon(rig):
    _, _, http = rig
    with http.stream("GET", "/api/stream?rate_hz=20&points=5&channels=e_x,e_y") as r:
        assert r.status_code == 200
        events = list(sse_events(r.iter_lines(), limit=6))
    assert events[0][0] == "subscribed" and events[0][1]["channels"] == ["e_x", "e_y"]
    updates = [e for n, e in events[1:] if n is None]
    assert len(updates) == 5
    seqs = [u["seq"] for u in updates]
    assert seqs == sorted(seqs) and seqs[-1] > seqs[0]
    for u in updates:
        assert set(u["min"]) == {"e_x", "e_y"} and 0 < len(u["min"]["e_x"]) <= 5
        assert "cycle" in u["status"] and "k_on" in u["status"]


def test_a_big_controller_upload_is_parsed_outside_the_daemon(rig, tmp_path):
    """Issue 21: an 810 kB controller uploaded with the token cost the loop 0.5 s of missed
    cycles (parsed in its process). The web server stores it as data; the daemon's socket
    process reads and validates it and the daemon gets its four matrices: it loads, and the
    daemon never read a file (``tests/service/test_read_outside_loop.py``)."""
    from bigcontroller import write_big_controller

    d, web, http = rig
    k = tmp_path / "big.yaml"
    write_big_controller(k)
    text = k.read_text()
    assert len(text) > 700_000
    seq0 = d.ctl_json("status")["seq"]
    r = http.post("/api/load", json={"upload": {"name": "big.yaml", "text": text}},
                  headers=_auth(web), timeout=600)
    assert r.status_code == 200, r.text
    st = d.ctl_json("status")
    assert st["controller"]["loaded"] and "big" in st["controller"]["source"], st["controller"]
    assert st["controller"]["order"] == 64
    assert st["seq"] > seq0 and st["fault"]["code"] == 0, st["fault"]
