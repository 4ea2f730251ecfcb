"""The token on every state-changing request, the body size limit, the one-line errors, and
the daemon unreachable: through the real app on a real control socket (loop double)."""

import json
import os
import stat

import pytest
from starlette.testclient import TestClient
from webkit import READ_TOKEN, TOKEN, auth

from rigd.errors import InputError
from rigd.web.app import Settings, build_app
from rigd.web.auth import load_or_create_token, token_ok
from rigd.web.guard import MAX_BODY

COMMANDS = ["enable", "disable", "reset", "load", "op", "start", "stop", "safe"]


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("header", [None, "Bearer wrong-token-0123456789", f"Basic {TOKEN}",
                                    f"Bearer {TOKEN}x", "Bearer "])
def test_no_or_wrong_token_is_401_and_nothing_reaches_the_daemon(site, name, header):
    client, loop, exps, _ = site
    body = {"op": {"omega_rpm": 1000, "p_inj_bar": 4},
            "load": {"path": "config/k.yaml"}}.get(name, {})
    del client.headers["Authorization"]
    headers = {"Authorization": header} if header is not None else {}
    r = client.post(f"/api/{name}", json=body, headers=headers)
    assert r.status_code == 401
    assert "token" in r.json()["error"] and r.headers["www-authenticate"] == "Bearer"
    assert loop.calls == [] and exps.started == []
    assert not loop.enabled


def test_with_the_token_the_command_reaches_the_daemon(site):
    client, loop, _, _ = site
    r = client.post("/api/enable", headers=auth())
    assert r.status_code == 200 and r.json() == {"enabled": True}
    assert loop.calls == [("enable_controller", True)] and loop.enabled
    r = client.post("/api/op", json={"omega_rpm": 2500, "p_inj_bar": 5}, headers=auth())
    assert r.status_code == 200 and loop.op == (2500, 5)


def test_cookies_carry_no_authority(site):
    client, loop, _, _ = site
    del client.headers["Authorization"]
    client.cookies.set("token", TOKEN)
    r = client.post("/api/enable", headers={"Cookie": f"Authorization=Bearer {TOKEN}"})
    assert r.status_code == 401 and loop.calls == []


def test_reads_with_either_token(site):
    client, loop, _, _ = site
    r = client.get("/api/status")
    assert r.status_code == 200 and r.json()["running"] is True
    assert r.json()["nan_field"] is None     # strict JSON, as `rigd ctl status --json`
    r = client.get("/api/status", headers=auth(READ_TOKEN))
    assert r.status_code == 200 and r.json()["running"] is True
    r = client.post("/api/enable", headers=auth(READ_TOKEN))
    assert r.status_code == 403 and "read-only" in r.json()["error"]
    assert loop.calls == [] and not loop.enabled


@pytest.mark.parametrize("url", ["/api/status", "/api/faults", "/api/timing", "/api/experiment",
                                 "/api/stream", "/api/runs", "/api/files", "/api/console",
                                 "/api/runs/r/rec.csv", "/runs/r/index.html", "/runs/r/k.yaml"])
def test_every_read_without_a_token_is_401(site, url):
    client, _, _, settings = site
    (settings.runs_dir / "r").mkdir()
    (settings.runs_dir / "r" / "index.html").write_text("<p>report</p>")
    (settings.runs_dir / "r" / "k.yaml").write_text("A: [[0.5]]\n")
    del client.headers["Authorization"]
    for headers in ({}, auth("wrong-token-0123456789"), {"Cookie": "rigd_session=forged"}):
        r = client.get(url, headers=headers)
        assert r.status_code == 401, (url, headers)
        assert "report" not in r.text and "0.5" not in r.text
    assert client.get("/").status_code == 200           # the page itself: no rig data
    assert client.get("/static/app.js").status_code == 200


def test_login_gives_a_read_only_session_cookie(site):
    client, loop, _, _ = site
    del client.headers["Authorization"]
    assert client.post("/api/login").status_code == 401
    r = client.post("/api/login", headers=auth(READ_TOKEN))
    assert r.status_code == 200 and r.json() == {"access": "read"}
    cookie = r.headers["set-cookie"]
    for attr in ("rigd_session=", "HttpOnly", "SameSite=Strict", "Path=/"):
        assert attr in cookie, cookie
    assert READ_TOKEN not in cookie and TOKEN not in cookie
    assert client.get("/api/status").status_code == 200     # the cookie, no header
    # the cookie carries reads only, even from the control token: no CSRF
    r = client.post("/api/login", headers=auth())
    assert r.status_code == 200 and r.json() == {"access": "control"}
    assert client.post("/api/enable").status_code == 401
    assert loop.calls == []
    assert client.post("/api/logout").status_code == 200
    assert client.get("/api/status").status_code == 401


def test_body_over_the_limit_is_413_before_anything_runs(site):
    client, loop, exps, _ = site
    big = {"upload": {"name": "x.yaml", "text": "#" * (MAX_BODY + 10)}}
    r = client.post("/api/start", json=big, headers=auth())
    assert r.status_code == 413 and "bytes" in r.json()["error"]

    def chunks():  # no Content-Length: counted as it streams
        for _ in range(MAX_BODY // 65536 + 2):
            yield b" " * 65536

    r = client.post("/api/start", content=chunks(), headers=auth())
    assert r.status_code == 413
    assert loop.calls == [] and exps.started == []
    assert not list((site[3].runs_dir).rglob("*.yaml")), "no upload kept"


def test_bad_requests_are_one_line_400(site):
    client, loop, _, _ = site
    for body, needle in [(b"{not json", "not JSON"), (b"[1]", "JSON object"),
                         (b'{"path": "config/x.yaml", "run_dir": "/tmp"}', "unknown field"),
                         (b"{}", "exactly one of")]:
        r = client.post("/api/start", content=body, headers=auth())
        assert r.status_code == 400, body
        err = r.json()["error"]
        assert needle in err and "\n" not in err
    r = client.post("/api/nonsense", headers=auth())
    assert r.status_code == 404 and "no command" in r.json()["error"]
    r = client.post("/api/op", json={"omega_rpm": -5, "p_inj_bar": 4}, headers=auth())
    assert r.status_code == 409 and "omega_rpm" in r.json()["error"]    # the daemon's line
    assert loop.calls == []


def test_daemon_not_reachable_is_503_one_line(tmp_path):
    s = Settings(socket=str(tmp_path / "none.sock"), runs_dir=tmp_path, config_dir=tmp_path,
                 token=TOKEN)
    with TestClient(build_app(s), headers=auth()) as client:
        for r in (client.get("/api/status"), client.post("/api/enable", headers=auth())):
            assert r.status_code == 503
            err = r.json()["error"]
            assert "daemon not reachable" in err and "none.sock" in err and "\n" not in err


def test_token_file_created_0600_reused_and_refused_when_readable(tmp_path):
    p = tmp_path / "tok"
    token, created = load_or_create_token(p)
    assert created and len(token) >= 32
    assert stat.S_IMODE(os.stat(p).st_mode) == 0o600
    assert load_or_create_token(p) == (token, False)
    os.chmod(p, 0o644)
    with pytest.raises(InputError, match="chmod 600"):
        load_or_create_token(p)
    os.chmod(p, 0o600)
    p.write_text("short\n")
    with pytest.raises(InputError, match="at least 16"):
        load_or_create_token(p)
    assert token_ok(f"Bearer {token}", token) and not token_ok(f"bearer {token}", token)
    assert not token_ok(None, token) and not token_ok(f"Bearer {token[:-1]}", token)


def test_static_page_and_plotly_served_from_the_package(site):
    client, _, _, _ = site
    r = client.get("/")
    assert r.status_code == 200 and "<title>rigd" in r.text
    r = client.get("/static/plotly.min.js")
    assert r.status_code == 200 and "plotly.js" in r.text[:2000]
    assert json.dumps({"a": 1})  # the page itself is checked by tests/browser


def test_daemon_silent_is_504_saying_it_may_have_been_applied(tmp_path):
    import socket
    import threading

    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(str(tmp_path / "mute.sock"))
    srv.listen(4)
    held, done = [], threading.Event()

    def accept():                      # accepts and reads, never answers
        while not done.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            held.append(conn)

    t = threading.Thread(target=accept, daemon=True)
    t.start()
    s = Settings(socket=str(tmp_path / "mute.sock"), runs_dir=tmp_path, config_dir=tmp_path,
                 token=TOKEN, timeout_s=0.3)
    try:
        with TestClient(build_app(s)) as client:
            r = client.post("/api/enable", headers=auth())
    finally:
        done.set()
        srv.close()
        for c in held:
            c.close()
        t.join(5)
    assert r.status_code == 504
    err = r.json()["error"]
    assert "controller.enable" in err and "never after" in err
    assert "\n" not in err
