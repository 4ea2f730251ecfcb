"""The idle rule of the control socket counts from a client's last complete request: a client
trickling a request byte by byte, never finishing it, loses its slot after the idle time; one
sending whole requests as often keeps it (a real daemon, ``--client-idle-s 2``)."""

import json
import socket
import time

from daemon_helpers import PROCESS_S, Daemon, make_config

IDLE_S = 2.0
EVERY_S = 0.2


def _connect(path):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(PROCESS_S)
    s.connect(path)
    return s


def _ask(s, buf=b""):
    s.sendall(b'{"id": 7, "cmd": "ping"}\n')
    while b"\n" not in buf:
        chunk = s.recv(65536)
        assert chunk, "the daemon closed a client that sends whole requests"
        buf += chunk
    line, _, rest = buf.partition(b"\n")
    return json.loads(line), rest


def _closed(s):
    """Has the daemon closed ``s`` (EOF or reset), without waiting?"""
    s.setblocking(False)
    try:
        data = s.recv(65536)
        return data == b""
    except BlockingIOError:
        return False
    except OSError:
        return True
    finally:
        s.settimeout(PROCESS_S)


def test_a_trickling_client_is_closed_a_working_one_is_not(tmp_path):
    d = Daemon(tmp_path, make_config(tmp_path), "--client-idle-s", str(IDLE_S))
    try:
        d.wait_notify("READY=1")
        working = _connect(d.sock)
        r, rest = _ask(working)
        assert r["ok"] and r["result"]["clients"] == 1, r
        trickle = _connect(d.sock)
        t0 = time.monotonic()
        request = b'{"id": 1, "cmd": "status"' + b" " * 10**6    # never its newline
        sent, closed_after = 0, None
        end = t0 + PROCESS_S                                    # a hang bound only
        while time.monotonic() < end:
            try:
                trickle.send(request[sent:sent + 1])
                sent += 1
            except OSError:
                closed_after = time.monotonic() - t0
                break
            if _closed(trickle):
                closed_after = time.monotonic() - t0
                break
            r, rest = _ask(working, rest)     # a whole request as often: kept
            assert r["ok"], r
            time.sleep(EVERY_S)
        assert closed_after is not None, f"a client trickling {sent} bytes kept its slot"
        # bytes kept coming (one every 0.2 s, as fast as the working client's requests were
        # answered): it was closed for finishing no request, and not before the idle time
        assert closed_after >= IDLE_S and sent >= 1, (closed_after, sent)
        r, rest = _ask(working, rest)
        assert r["ok"] and r["result"]["clients"] == 1, r
        trickle.close()
        working.close()
    finally:
        d.stop()
