"""The one-click login URL that ``rigd web`` prints at start (docs/web.md, "Log in"): it carries
the control token in its fragment, which the server never sees; the read-only URL carries the
read-only token; both name the address the console answers on."""

from urllib.parse import parse_qs, urlsplit

import httpx2 as httpx
import pytest
from webproc import WebProcess

from rigd.cli.web import base_url, login_url


def _fragment_token(url: str) -> str:
    (tk,) = parse_qs(urlsplit(url).fragment, strict_parsing=True)["token"]
    return tk


@pytest.fixture(scope="module")
def web(tmp_path_factory):
    """A real ``rigd web`` (no daemon needed to serve the page and log in)."""
    tmp = tmp_path_factory.mktemp("loginurl")
    (tmp / "config").mkdir()
    w = WebProcess(tmp, str(tmp / "no-daemon.sock"), tmp / "runs", tmp / "config")
    try:
        yield w
    finally:
        w.stop()


def test_the_printed_url_carries_the_control_token_in_its_fragment(web):
    parts = urlsplit(web.login_url)
    # the console's own address, the token only in the fragment (never sent in a request)
    assert f"{parts.scheme}://{parts.netloc}" == web.url and parts.path == "/"
    assert parts.query == ""
    assert _fragment_token(web.login_url) == web.token
    assert _fragment_token(web.read_login_url) == web.read_token
    assert urlsplit(web.read_login_url)._replace(fragment="") == parts._replace(fragment="")
    # the open line is the last start line: what the operator clicks
    assert web.lines[-1] == f"rigd web: open {web.login_url}"


def test_the_url_grants_what_the_operator_of_rigd_web_may_do(web):
    """The control token of the URL logs in with control access; the read-only URL's with
    reads only: its command is refused (403) before the daemon is asked."""
    with httpx.Client(base_url=web.url, timeout=60) as http:
        page = http.get(urlsplit(web.login_url)._replace(fragment="").geturl())
        assert page.status_code == 200 and 'id="token-save"' in page.text
        for url, access in ((web.login_url, "control"), (web.read_login_url, "read")):
            r = http.post("/api/login",
                          headers={"Authorization": f"Bearer {_fragment_token(url)}"})
            assert r.status_code == 200 and r.json() == {"access": access}
        r = http.post("/api/enable", json={},
                      headers={"Authorization": f"Bearer {_fragment_token(web.read_login_url)}"})
        assert r.status_code == 403


def test_a_token_read_from_its_file_is_in_the_url_too(web, tmp_path):
    """Not only a new token: every start prints the URL (the token file is kept)."""
    (tmp_path / "config").mkdir()
    tok = tmp_path / "web-token"
    tok.write_text(web.token + "\n")
    tok.chmod(0o600)
    again = WebProcess(tmp_path, str(tmp_path / "no-daemon.sock"), tmp_path / "runs",
                       tmp_path / "config", args={"--token-file": str(tok)})
    try:
        assert any(ln == f"rigd web: token from {tok}" for ln in again.lines)
        assert _fragment_token(again.login_url) == web.token
    finally:
        again.stop()


def test_login_url_quotes_the_token_and_names_a_reachable_host():
    assert login_url("http://127.0.0.1:8080/", "a+b/c=d&e#f") == \
        "http://127.0.0.1:8080/#token=a%2Bb%2Fc%3Dd%26e%23f"
    assert _fragment_token(login_url("http://h:1/", "a+b/c=d&e#f")) == "a+b/c=d&e#f"
    assert base_url("127.0.0.1", 8080, False) == "http://127.0.0.1:8080/"
    assert base_url("::1", 8080, True) == "https://[::1]:8080/"
    # on every address: the name the TLS certificate is for (--allow-host), else the machine's
    assert base_url("0.0.0.0", 8443, True, ["rig.lab"]) == "https://rig.lab:8443/"
    assert not base_url("0.0.0.0", 8443, True).startswith("https://0.0.0.0")
