"""More browsers than ``rigd web``'s stream limit (``MAX_STREAMS``, 256) ask at once — every
request sent before any answer is read: exactly the limit are streamed (200), every other one
is refused with 503 and one line, the daemon holds one client for all of them, and SAFE still
latches; once the streams close their places are free again (the 16-stream limit of issue 21
raced: 80 concurrent streams all got 200)."""

from __future__ import annotations

import json
import time

import httpx2 as httpx
from daemon_helpers import PROCESS_S
from test_safe_under_siege import _head, _open_stream, _ping
from webproc import daemon_and_web

from rigd.web.app import MAX_STREAMS

#: streams asked for beyond the limit
N_OVER = 40


def test_exactly_the_stream_limit_is_taken_when_more_race_for_it(tmp_path):
    with daemon_and_web(tmp_path) as (d, web):
        clients0 = _ping(d.sock)["clients"]
        socks = [_open_stream(web.url, web.token) for _ in range(MAX_STREAMS + N_OVER)]
        try:
            heads = [_head(s) for s in socks]
            codes = [h.split(b" ", 2)[1] for h in heads]
            assert codes.count(b"200") == MAX_STREAMS, sorted(set(codes))
            assert codes.count(b"503") == N_OVER, sorted(set(codes))
            refused = [h for h in heads if h.split(b" ", 2)[1] == b"503"]
            body = json.loads(_rest(socks[heads.index(refused[0])], refused[0]))
            assert body["error"] == f"too many stream clients (at most {MAX_STREAMS})"
            # the 256 browsers cost the daemon one subscription, one client
            assert _ping(d.sock)["clients"] <= clients0 + 1
            r = httpx.post(f"{web.url}/api/safe", headers=web.auth(), timeout=PROCESS_S)
            assert r.status_code == 200, r.text
            assert d.ctl_json("status")["fault"]["name"] == "operator_safe"
        finally:
            for s in socks:
                s.close()
        # every place is released however its stream ended: a new browser gets one
        s = _open_stream(web.url, web.token)
        try:
            for _ in range(int(PROCESS_S)):
                head = _head(s)
                if head.startswith(b"HTTP/1.1 200"):
                    break
                s.close()
                time.sleep(0.1)
                s = _open_stream(web.url, web.token)
            assert head.startswith(b"HTTP/1.1 200"), head
        finally:
            s.close()


def _rest(s, head: bytes) -> bytes:
    """The body of a refused (closed, Content-Length) response after its ``head``."""
    buf = head.split(b"\r\n\r\n", 1)[1]
    n = int(next(x for x in head.split(b"\r\n") if x.lower().startswith(b"content-length"))
            .split(b":")[1])
    while len(buf) < n:
        chunk = s.recv(4096)
        if not chunk:
            break
        buf += chunk
    return buf[:n]
