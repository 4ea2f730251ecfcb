"""``rigd web`` arguments and start-up errors (one line, exit 2, before serving), the Host
check on loopback, the security headers."""

import os
import socket

import pytest
from starlette.testclient import TestClient
from webkit import TOKEN, auth

from rigd.cli import main
from rigd.cli.web import LOOPBACK_NAMES, allowed_hosts, parse_listen
from rigd.web.app import Settings, build_app


def test_parse_listen():
    assert parse_listen("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert parse_listen("[::1]:0") == ("::1", 0)
    for bad in ("8080", "host:", ":80", "127.0.0.1:http", "127.0.0.1:70000"):
        with pytest.raises(Exception, match="HOST:PORT"):
            parse_listen(bad)


@pytest.mark.parametrize("case", ["listen", "config", "token_mode", "port_taken",
                                  "not_loopback", "tls_half", "read_same", "header_timeout"])
def test_start_up_errors_are_one_line_exit_2(case, tmp_path, capsys):
    (tmp_path / "config").mkdir()
    args = ["web", "--socket", str(tmp_path / "s.sock"), "--runs-dir", str(tmp_path / "runs"),
            "--config-dir", str(tmp_path / "config"), "--token-file", str(tmp_path / "tok"),
            "--listen", "127.0.0.1:0"]
    held = None
    if case == "listen":
        args[-1] = "everywhere"
        needle = "--listen 'everywhere'"
    elif case == "config":
        args[args.index("--config-dir") + 1] = str(tmp_path / "nope")
        needle = "nope: no such folder (--config-dir)"
    elif case == "token_mode":
        (tmp_path / "tok").write_text("x" * 40 + "\n")
        os.chmod(tmp_path / "tok", 0o644)
        needle = "chmod 600"
    elif case == "not_loopback":
        args[-1] = "0.0.0.0:0"
        needle = "is not a loopback address: give --tls-cert/--tls-key (or --insecure"
    elif case == "tls_half":
        args += ["--tls-key", str(tmp_path / "k.pem")]
        needle = "--tls-cert and --tls-key go together"
    elif case == "read_same":
        (tmp_path / "tok").write_text("x" * 40 + "\n")
        os.chmod(tmp_path / "tok", 0o600)
        args += ["--read-token-file", str(tmp_path / "tok")]
        needle = "the read-only token must differ"
    elif case == "header_timeout":
        args += ["--header-timeout", "0"]
        needle = "--header-timeout 0: expected 0 < S <= 3600"
    else:
        held = socket.socket()
        held.bind(("127.0.0.1", 0))
        held.listen(1)
        args[-1] = f"127.0.0.1:{held.getsockname()[1]}"
        needle = "cannot listen on 127.0.0.1"
    try:
        assert main(args) == 2
    finally:
        if held is not None:
            held.close()
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigd web: ") and needle in err and len(err.splitlines()) == 1, err


def test_only_the_listen_address_names_are_accepted(tmp_path):
    assert allowed_hosts("192.168.1.5") == ("192.168.1.5",)
    assert allowed_hosts("192.168.1.5", ["Rig.Example"]) == ("192.168.1.5", "rig.example")
    anywhere = allowed_hosts("0.0.0.0")
    assert set(LOOPBACK_NAMES) <= set(anywhere) and socket.gethostname().lower() in anywhere
    hosts = allowed_hosts("127.0.0.1")
    assert set(hosts) == set(LOOPBACK_NAMES) == set(allowed_hosts("localhost"))
    s = Settings(socket=str(tmp_path / "none.sock"), runs_dir=tmp_path, config_dir=tmp_path,
                 token=TOKEN, allowed_hosts=hosts)
    app = build_app(s)
    with TestClient(app, base_url="http://attacker.example:8080", headers=auth()) as client:
        r = client.get("/api/status")
        assert r.status_code == 400 and "daemon" not in r.text
    for base in ("http://127.0.0.1:8080", "http://localhost:8080"):
        with TestClient(app, base_url=base, headers=auth()) as client:
            assert client.get("/api/status").status_code == 503    # past the check: no daemon


def test_security_headers(tmp_path):
    s = Settings(socket=str(tmp_path / "none.sock"), runs_dir=tmp_path, config_dir=tmp_path,
                 token=TOKEN)
    with TestClient(build_app(s), headers=auth()) as client:
        page = client.get("/")
        csp = page.headers["content-security-policy"]
        assert "script-src 'self'" in csp and "frame-ancestors 'none'" in csp
        # no string run as code on the console page (the browser tests run it under this)
        script_src = csp.split("script-src")[1].split(";")[0]
        assert "unsafe-eval" not in script_src and "unsafe-inline" not in script_src
        for r in (page, client.get("/api/status"), client.get("/static/app.js")):
            assert r.headers["x-content-type-options"] == "nosniff"
            assert r.headers["x-frame-options"] == "DENY"
