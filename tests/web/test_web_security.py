"""The web attacks of issue 21 against a real ``rigd web`` process (and a real daemon,
``rigd run`` on the simulated rig): reads need a token, the read-only token reads only, the
session cookie carries reads only. Every row of docs/web.md's attack table names its test."""

import json
import ssl

import httpx2 as httpx
import numpy as np
import pytest
from webproc import WebProcess, config_folder, sse_events, start_daemon

from rigd.data.csvio import write_csv
from rigd.data.record import Record

REPORT = "<html><body><p>report of the secret run</p></body></html>"


def _runs_folder(tmp):
    """A runs folder with a run: a record, a report page and a model file."""
    run = tmp / "runs" / "20260101T000000Z-prbs"
    run.mkdir(parents=True)
    n = 2000
    t = np.arange(n) / 5000.0
    z = np.zeros(n)
    cols = {"t": t, "r_x": z, "r_y": z, "u_x": z, "u_y": z, "e_x": np.sin(t), "e_y": np.cos(t)}
    write_csv(run / "rec.csv", Record(cols, 5000.0, {"omega_rpm": 0.0, "p_inj_bar": 4.0,
                                                     "kind": "prbs"}))
    (run / "index.html").write_text(REPORT)
    (run / "controller.yaml").write_text("A: [[0.5]]\n")
    return tmp / "runs"


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("websec")
    d = start_daemon(tmp)
    try:
        cfg, runs = config_folder(tmp), _runs_folder(tmp)
        web = WebProcess(tmp, d.sock, runs, cfg)
        try:
            yield d, web, tmp
        finally:
            web.stop()
    finally:
        d.stop()


READS = ["/api/status", "/api/faults", "/api/timing", "/api/experiment", "/api/console",
         "/api/files", "/api/runs", "/api/runs/20260101T000000Z-prbs/rec.csv?points=100",
         "/runs/20260101T000000Z-prbs/index.html", "/runs/20260101T000000Z-prbs/controller.yaml"]


def _first_event(client, **kw):
    with client.stream("GET", "/api/stream?rate_hz=20&points=5&channels=e_x", **kw) as r:
        if r.status_code != 200:
            return r.status_code, r.read().decode()
        return r.status_code, next(sse_events(r.iter_lines(), limit=1))


def test_every_read_needs_a_token(rig):
    """Status, faults, stream, runs, records, reports and model files: 401 without a token
    (or with a wrong one, or a forged cookie), 200 with either token."""
    _, web, _ = rig
    with httpx.Client(base_url=web.url, timeout=60) as http:
        for url in READS:
            for headers in ({}, {"Authorization": "Bearer wrong-token-0123456789"},
                            {"Cookie": "rigd_session=forged-session-id"}):
                r = http.get(url, headers=headers)
                assert r.status_code == 401, (url, headers, r.status_code)
                assert r.json()["error"].startswith("missing or wrong token")
                assert "secret run" not in r.text and "0.5" not in r.text
            for read in (False, True):
                r = http.get(url, headers=web.auth(read=read))
                assert r.status_code == 200, (url, read, r.text)
        status, body = _first_event(http)
        assert status == 401 and "token" in body
        status, (name, sub) = _first_event(http, headers=web.auth(read=True))
        assert status == 200 and name == "subscribed" and sub["channels"] == ["e_x"]
        assert http.get("/").status_code == 200            # the page: no rig data in it


def test_login_cookie_reads_but_never_commands(rig):
    """``POST /api/login`` turns a token into a read-only session cookie (what EventSource
    and report links carry); no token in any URL; the cookie changes nothing."""
    d, web, _ = rig
    with httpx.Client(base_url=web.url, timeout=60) as http:
        assert http.post("/api/login").status_code == 401
        r = http.post("/api/login", headers=web.auth())
        assert r.status_code == 200 and r.json() == {"access": "control"}
        cookie = r.headers["set-cookie"]
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
        assert web.token not in cookie and web.read_token not in cookie
        for url in READS:
            assert http.get(url).status_code == 200, url      # the cookie alone
        status, (name, _) = _first_event(http)
        assert status == 200 and name == "subscribed"
        before = d.ctl_json("status")
        for cmd in ("enable", "safe"):
            assert http.post(f"/api/{cmd}", json={}).status_code == 401
        after = d.ctl_json("status")
        assert not after["controller"]["requested"] and after["fault"]["code"] == 0
        assert after["controller"]["source"] == before["controller"]["source"]
        assert http.post("/api/logout").status_code == 200
        assert http.get("/api/status").status_code == 401


def test_read_only_token_commands_nothing(rig):
    d, web, _ = rig
    with httpx.Client(base_url=web.url, timeout=60, headers=web.auth(read=True)) as http:
        for cmd, body in [("enable", {}), ("safe", {}), ("op", {"omega_rpm": 900,
                                                                 "p_inj_bar": 4}),
                          ("load", {"path": "config/controller-k.yaml"}),
                          ("start", {"path": "config/experiments/web-short.yaml"})]:
            r = http.post(f"/api/{cmd}", json=body)
            assert r.status_code == 403 and "read-only" in r.json()["error"], cmd
        assert json.loads(http.post("/api/login").text) == {"access": "read"}
    st = d.ctl_json("status")
    assert not st["controller"]["requested"] and st["fault"]["code"] == 0
    assert st["last_frame"]["omega_rpm"] == 0.0
    assert d.ctl_json("experiment").get("name") != "web-short"


# ---------------------------------------------------------------- uploads: data only

BAD_CONTROLLER_HTML = "<script>fetch('/api/safe')</script>\nA: [[1.5]]\n"


def _uploads(tmp):
    up = tmp / "runs" / "uploads"
    return sorted(p.name for p in up.iterdir()) if up.is_dir() else []


def test_rejected_uploads_are_not_kept_nor_listed(rig):
    """A rejected upload (the daemon's or the console's own refusal) leaves no file, is not
    offered in the controller list and no ``uploads`` folder shows on the Runs tab."""
    d, web, tmp = rig
    before = _uploads(tmp)
    with httpx.Client(base_url=web.url, timeout=60, headers=web.auth()) as http:
        r = http.post("/api/load", json={"upload": {"name": "x.html",
                                                    "text": BAD_CONTROLLER_HTML}})
        assert r.status_code in (400, 409) and "\n" not in r.json()["error"]
        r = http.post("/api/start", json={"upload": {"name": "x.html", "text": "kind: nope\n"}})
        assert r.status_code == 400
        assert _uploads(tmp) == before
        files = http.get("/api/files").json()
        assert not any("x.html" in f or "uploads" in f for f in files["runs"]), files
        runs = http.get("/api/runs").json()
        assert "uploads" not in {r["name"] for r in runs}
    assert d.ctl_json("status")["controller"]["source"].endswith("k.yaml")


def test_kept_upload_is_served_as_an_attachment_never_html(rig):
    """An accepted upload named ``k.html`` is stored as YAML data and served as a plain-text
    attachment (``nosniff``, a content security policy that runs nothing)."""
    d, web, tmp = rig
    text = (tmp / "k.yaml").read_text() + "# <script>alert(1)</script>\n"
    with httpx.Client(base_url=web.url, timeout=60, headers=web.auth()) as http:
        r = http.post("/api/load", json={"upload": {"name": "k.html", "text": text}})
        assert r.status_code == 200, r.text
        [name] = [n for n in _uploads(tmp) if "k.html" in n or n.endswith("-k.yaml")]
        assert name.endswith(".yaml") and ".html" not in name
        f = http.get(f"/runs/uploads/{name}")
        assert f.status_code == 200 and f.text == text
        assert f.headers["content-type"].startswith("text/plain")
        assert f.headers["content-disposition"].startswith("attachment")
        assert f.headers["x-content-type-options"] == "nosniff"
        assert "default-src 'none'" in f.headers["content-security-policy"]
        assert "uploads" not in {r["name"] for r in http.get("/api/runs").json()}
    assert d.ctl_json("status")["controller"]["source"].endswith(name)


def test_every_response_has_a_content_security_policy(rig):
    _, web, _ = rig
    with httpx.Client(base_url=web.url, timeout=60) as http:
        page = http.get("/")
        assert "script-src 'self'" in page.headers["content-security-policy"]
        report = http.get("/runs/20260101T000000Z-prbs/index.html", headers=web.auth())
        assert report.headers["content-type"].startswith("text/html")
        csp = report.headers["content-security-policy"]
        assert "connect-src 'none'" in csp and "frame-ancestors 'none'" in csp
        for r in (http.get("/api/status", headers=web.auth()), http.get("/api/status"),
                  http.get("/static/app.js"), http.get("/nowhere", headers=web.auth()),
                  http.get("/runs/20260101T000000Z-prbs/controller.yaml", headers=web.auth())):
            assert r.headers["content-security-policy"], r.url
            assert r.headers["x-content-type-options"] == "nosniff", r.url


# ---------------------------------------------------------------- bounded requests

def _raw(web, data: bytes, timeout=60.0) -> bytes:
    """Send raw bytes, return everything the server answers until it closes or pauses."""
    import socket
    from urllib.parse import urlsplit

    u = urlsplit(web.url)
    with socket.create_connection((u.hostname, u.port), timeout=timeout) as s:
        s.sendall(data)
        out = b""
        while b"\r\n\r\n" not in out or len(out) < 12:
            chunk = s.recv(65536)
            if not chunk:
                break
            out += chunk
        return out


def _status(raw: bytes) -> int:
    return int(raw.split(b" ", 2)[1])


@pytest.mark.parametrize("case", ["deep_array", "deep_in_object", "long_path", "long_name",
                                  "long_static", "long_query", "huge_header", "many_headers"])
def test_hostile_requests_are_4xx_never_500(rig, case):
    d, web, _ = rig
    tok = f"Authorization: Bearer {web.token}\r\n".encode()
    if case.startswith("deep"):
        deep = b"[" * 200_000 + b"]" * 200_000
        body = deep if case == "deep_array" else b'{"path": ' + deep + b"}"
        head = (b"POST /api/load HTTP/1.1\r\nHost: 127.0.0.1\r\n" + tok
                + b"Content-Type: application/json\r\nContent-Length: %d\r\n\r\n" % len(body))
        req = head + body
    else:
        target = {"long_path": "/runs/" + "a/" * 2500, "long_name": "/runs/" + "a" * 1500,
                  "long_static": "/static/" + "a" * 1500,
                  "long_query": "/api/status?x=" + "a" * 5000}.get(case, "/api/status")
        extra = {"huge_header": b"X-Big: " + b"a" * 40_000 + b"\r\n",
                 "many_headers": b"".join(b"X-%d: a\r\n" % i for i in range(3000))}.get(case, b"")
        req = (f"GET {target} HTTP/1.1\r\nHost: 127.0.0.1\r\n".encode() + tok + extra
               + b"Connection: close\r\n\r\n")
    answer = _raw(web, req)
    assert 400 <= _status(answer) < 500, (case, answer[:200])
    with httpx.Client(base_url=web.url, timeout=60, headers=web.auth()) as http:
        assert http.get("/api/status").status_code == 200       # still serving
    assert d.ctl_json("status")["controller"]["source"].endswith("k.yaml")


# ---------------------------------------------------------------- symlinks out of the runs folder

def test_symlinks_out_of_the_runs_folder_are_neither_followed_nor_listed(rig):
    """A runs folder with a symlink to /usr (once 7.3 s and 427 outside names listed): no
    outside name in the listing, the controller list or a run's files; nothing served."""
    import os

    _, web, tmp = rig
    runs = tmp / "runs"
    run = runs / "20260101T000000Z-prbs"
    outside = tmp / "outside"
    outside.mkdir()
    (outside / "controller-out.yaml").write_text("A: [[0.5]]\n")
    (outside / "page.html").write_text("<p>outside page</p>")
    links = [(runs / "usr", "/usr"), (run / "lib", "/usr/lib"), (runs / "out", outside),
             (runs / "controller-link.yaml", outside / "controller-out.yaml"),
             (run / "outside.html", outside / "page.html")]
    for link, target in links:
        os.symlink(target, link)
    try:
        with httpx.Client(base_url=web.url, timeout=120, headers=web.auth()) as http:
            listing = http.get("/api/runs")
            assert listing.status_code == 200
            text = listing.text
            assert '"usr"' not in text and '"out"' not in text and "lib" not in text
            [entry] = [r for r in listing.json() if r["name"] == run.name]
            assert entry["records"] == ["rec.csv"] and entry["pages"] == ["index.html"]
            files = http.get("/api/files").json()
            assert not any("link" in f or "out" in f for f in files["runs"]), files
            for url in ("/runs/usr/bin/env", f"/runs/{run.name}/lib/os.py", "/runs/out/page.html",
                        f"/runs/{run.name}/outside.html", "/runs/controller-link.yaml",
                        "/api/runs/out/rec.csv"):
                r = http.get(url)
                assert r.status_code == 404, (url, r.status_code)
                assert "outside page" not in r.text
    finally:
        for link, _ in links:
            link.unlink()


# ---------------------------------------------------------------- slow clients, descriptors

def _other_web(rig, name, args=None, preexec_fn=None):
    d, _, tmp = rig
    return WebProcess(tmp, d.sock, tmp / "runs", tmp / "config", args=args,
                      preexec_fn=preexec_fn, name=name)


def _slow_socket(web, head=b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\n"):
    """A connection that sends part of a request head and then nothing."""
    import socket
    from urllib.parse import urlsplit

    u = urlsplit(web.url)
    s = socket.create_connection((u.hostname, u.port), timeout=120)
    s.sendall(head)
    return s


def test_slow_request_heads_and_bodies_time_out(rig):
    web = _other_web(rig, "slowhead", {"--header-timeout": "1"})
    try:
        fresh = _slow_socket(web, b"")
        partial = _slow_socket(web)
        assert fresh.recv(100) == b"" and partial.recv(100) == b""      # closed by the server
        # an idle keep-alive connection that then starts a request head and stalls
        kept = _slow_socket(web, b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        first = kept.recv(65536)
        assert first.startswith(b"HTTP/1.1 200")
        kept.sendall(b"GET / HTTP/1.1\r\n")
        while True:
            chunk = kept.recv(65536)
            if not chunk:
                break
        # a body that stalls: 408 from the guard
        body = _slow_socket(web, b"POST /api/op HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: "
                            b"Bearer " + web.token.encode() + b"\r\nContent-Length: 100\r\n\r\n{")
        answer = body.recv(65536)
        assert answer.startswith(b"HTTP/1.1 408"), answer[:100]
        for s in (fresh, partial, kept, body):
            s.close()
        with httpx.Client(base_url=web.url, timeout=60, headers=web.auth()) as http:
            assert http.get("/api/status").status_code == 200
    finally:
        web.stop()
    assert rig[0].ctl_json("status")["last_frame"]["omega_rpm"] == 0.0    # the stalled op


def _limit_descriptors(n):
    def set_limit():
        import resource
        resource.setrlimit(resource.RLIMIT_NOFILE, (n, n))
    return set_limit


def test_more_slow_sockets_than_descriptors_and_it_keeps_answering(rig):
    """``rigd web`` with 64 descriptors (58 slow sockets once exhausted them): 100 slow
    sockets that never finish their request head, and the console still answers (the
    oldest slow connections are closed to make room)."""
    web = _other_web(rig, "fds", {"--header-timeout": "600"}, _limit_descriptors(64))
    held = []
    try:
        with httpx.Client(base_url=web.url, timeout=60, headers=web.auth()) as http:
            for _ in range(100):
                held.append(_slow_socket(web))
            for _ in range(3):
                r = http.get("/api/status", headers={"Connection": "close"})
                assert r.status_code == 200 and r.json()["running"], r.text
                for _ in range(20):
                    held.append(_slow_socket(web))
        closed = 0
        for s in held:
            s.settimeout(0.5)
            try:
                closed += s.recv(100) == b""
            except ConnectionResetError:
                closed += 1
            except TimeoutError:
                pass                               # still open
        assert closed >= 100 - 64, closed          # the server made room by closing them
        assert web.proc.poll() is None
    finally:
        for s in held:
            s.close()
        web.stop()


# ---------------------------------------------------------------- TLS, listen address, Host

@pytest.fixture(scope="module")
def cert(tmp_path_factory):
    """A self-signed certificate for 127.0.0.1 and localhost (openssl)."""
    import shutil
    import subprocess

    if shutil.which("openssl") is None:
        pytest.skip("openssl not installed")
    tmp = tmp_path_factory.mktemp("tls")
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt",
                    "ec_paramgen_curve:prime256v1", "-nodes", "-days", "2", "-subj",
                    "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost",
                    "-keyout", str(tmp / "key.pem"), "-out", str(tmp / "cert.pem")],
                   check=True, capture_output=True)
    return tmp / "cert.pem", tmp / "key.pem"


def test_tls_serves_https_and_the_cookie_is_secure(rig, cert):
    crt, key = cert
    web = _other_web(rig, "tls", {"--tls-cert": str(crt), "--tls-key": str(key)})
    try:
        assert web.url.startswith("https://127.0.0.1:")
        trust = ssl.create_default_context(cafile=str(crt))
        with httpx.Client(base_url=web.url, timeout=60, verify=trust) as https:
            assert https.get("/api/status").status_code == 401
            r = https.post("/api/login", headers=web.auth(read=True))
            assert r.status_code == 200 and "; Secure" in r.headers["set-cookie"]
            assert https.get("/api/status").status_code == 200
        plain = web.url.replace("https://", "http://")
        with pytest.raises(httpx.HTTPError):
            httpx.get(plain + "/api/status", headers=web.auth(), timeout=30)
    finally:
        web.stop()


def test_non_loopback_listen_needs_tls_or_insecure(rig, cert):
    import subprocess

    from daemon_helpers import RIGD

    d, _, tmp = rig
    base = [RIGD, "web", "--socket", d.sock, "--runs-dir", str(tmp / "runs"), "--config-dir",
            str(tmp / "config"), "--token-file", str(tmp / "web-token")]
    r = subprocess.run(base + ["--listen", "0.0.0.0:0"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "not a loopback address" in r.stderr and "--tls-cert" in r.stderr
    r = subprocess.run(base + ["--listen", "0.0.0.0:0", "--tls-cert", str(cert[0])],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--tls-cert and --tls-key go together" in r.stderr
    r = subprocess.run(base + ["--listen", "127.0.0.1:0", "--tls-cert", str(cert[1]),
                               "--tls-key", str(cert[1])], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and "cannot use --tls-cert/--tls-key" in r.stderr
    web = _other_web(rig, "insecure", {"--listen": "0.0.0.0:0", "--insecure": None,
                                       "--allow-host": "rig.example"})
    try:
        assert any("WARNING: --insecure: plain HTTP on 0.0.0.0" in x for x in web.lines)
        port = web.url.rsplit(":", 1)[1]
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60,
                          headers=web.auth()) as http:
            assert http.get("/api/status").status_code == 200
            assert http.get("/api/status", headers={"Host": "rig.example"}).status_code == 200
            r = http.get("/api/status", headers={"Host": "attacker.example"})
            assert r.status_code == 400 and "Host" in r.json()["error"]
    finally:
        web.stop()
    web = _other_web(rig, "tlsany", {"--listen": "0.0.0.0:0", "--tls-cert": str(cert[0]),
                                     "--tls-key": str(cert[1])})
    try:
        assert not any("WARNING" in x for x in web.lines)
        port = web.url.rsplit(":", 1)[1]
        trust = ssl.create_default_context(cafile=str(cert[0]))
        with httpx.Client(base_url=f"https://127.0.0.1:{port}", timeout=60, verify=trust,
                          headers=web.auth()) as https:
            assert https.get("/api/status").status_code == 200
    finally:
        web.stop()


@pytest.mark.parametrize("host", ["attacker.example", "attacker.example:8080", "127.0.0.1.nip.io",
                                  "localhost.attacker.example", ""])
def test_dns_rebinding_host_names_are_refused(rig, host):
    """A page of another domain re-pointed at 127.0.0.1 sends its own name: 400 before any
    route, token or not."""
    _, web, _ = rig
    port = web.url.rsplit(":", 1)[1]
    req = (f"GET /api/status HTTP/1.1\r\nHost: {host}\r\nAuthorization: Bearer {web.token}\r\n"
           "Connection: close\r\n\r\n").encode()
    answer = _raw(web, req)
    assert _status(answer) == 400, answer[:200]
    assert b'"running"' not in answer
    for ok in ("127.0.0.1", f"127.0.0.1:{port}", "localhost", f"localhost:{port}"):
        req = (f"GET /api/status HTTP/1.1\r\nHost: {ok}\r\nAuthorization: Bearer {web.token}"
               "\r\nConnection: close\r\n\r\n").encode()
        assert _status(_raw(web, req)) == 200, ok
