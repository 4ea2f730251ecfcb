"""A short socket load test against the real daemon: many clients, malformed requests, every
reply checked, the daemon alive and its loop cycling afterwards (no timed asserts; the timed
figures come from `python -m bench socket_load`)."""

import socket

from bench.socket_load import _call, hammer, start_daemon, stop_daemon


def test_socket_load_short(tmp_path):
    proc, sock = start_daemon(tmp_path)
    try:
        seq0 = _call(sock, "status")["seq"]
        ran0 = _call(sock, "ping")["commands_run"]
        # at least 25 requests per client however slow the machine (a fixed 2 s window gave
        # 22 requests on a loaded one); each client's mix is drawn from its own seed
        res = hammer(sock, clients=12, rate=300.0, seconds=2.0, seed=7, min_requests=25)
        assert res["errors"] == 0, res
        assert res["served"] > 100 and res["refused"] > 20
        # queries and bad requests were all answered by the socket process: not one of them
        # reached the loop's process
        assert _call(sock, "ping")["commands_run"] == ran0
        # a client that never ends its line and one that vanishes mid-request change nothing
        idle = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        idle.connect(sock)
        idle.sendall(b'{"cmd": "sta')
        gone = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        gone.connect(sock)
        gone.sendall(b'{"cmd": "status"}\n')
        gone.close()
        st = _call(sock, "status")
        assert st["running"] and st["seq"] > seq0 and st["fault"]["code"] == 0
        assert _call(sock, "ping")["pong"] is True
        idle.close()
    finally:
        code = stop_daemon(proc)
    assert code == 0
