"""sd_notify against real Unix datagram sockets (path and abstract namespace)."""

import os
import socket

import pytest

from rigd.service.notify import Notifier


def _recv(sock):
    sock.settimeout(2.0)
    return sock.recv(4096).decode()


def test_notify_path_socket(tmp_path):
    path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    try:
        n = Notifier(environ={"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "2000000",
                              "WATCHDOG_PID": str(os.getpid())})
        assert n.enabled and n.watchdog_interval_s == pytest.approx(1.0)
        assert n.ready("loop running")
        msg = _recv(srv).split("\n")
        assert "READY=1" in msg and "STATUS=loop running" in msg
        assert f"MAINPID={os.getpid()}" in msg
        n.watchdog()
        assert _recv(srv) == "WATCHDOG=1"
        n.status("two\nlines")
        assert _recv(srv) == "STATUS=two lines"
        n.stopping()
        assert _recv(srv) == "STOPPING=1"
        assert n.sent == 4 and n.errors == 0
        n.close()
    finally:
        srv.close()


def test_notify_abstract_socket():
    name = f"rigd-test-{os.getpid()}"
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind("\0" + name)
    try:
        n = Notifier(environ={"NOTIFY_SOCKET": "@" + name})
        assert n.watchdog_interval_s == 0.0
        assert n.ready()
        assert "READY=1" in _recv(srv)
    finally:
        srv.close()


def test_notify_disabled_and_broken(tmp_path):
    n = Notifier(environ={})
    assert not n.enabled and not n.ready()
    # watchdog meant for another pid is ignored
    assert Notifier(environ={"WATCHDOG_USEC": "1000", "WATCHDOG_PID": "1"}).watchdog_s == 0
    # nobody listening: counted, never raised
    n = Notifier(environ={"NOTIFY_SOCKET": str(tmp_path / "absent.sock")})
    assert not n.ready() and n.errors == 1


def test_notify_never_blocks_on_a_full_queue(tmp_path):
    path = str(tmp_path / "full.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    try:
        n = Notifier(environ={"NOTIFY_SOCKET": path})
        results = [n.watchdog() for _ in range(5000)]  # nobody reads: the queue fills up
        assert results[0] and not results[-1] and n.errors > 0
    finally:
        srv.close()


def test_start_up_is_extended_while_compiling_until_ready(tmp_path):
    """EXTEND_TIMEOUT_USEC is sent while the daemon starts (a cold numba cache compiles for
    tens of seconds) and stops with READY=1; without NOTIFY_SOCKET nothing runs."""
    import time

    from rigd.service import notify

    path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    notify._READY.clear()                # a READY=1 sent by another test of this process
    try:
        assert not notify.extend_start_up(environ={})
        assert notify.extend_start_up(environ={"NOTIFY_SOCKET": path}, every_s=0.05,
                                      by_s=30.0, max_s=60.0)
        msgs = [_recv(srv) for _ in range(2)]
        for m in msgs:
            assert "EXTEND_TIMEOUT_USEC=30000000" in m.split("\n")
            assert "STATUS=starting: compiling" in m
        assert Notifier(environ={"NOTIFY_SOCKET": path}).ready("up")
        end = time.monotonic() + 5
        while "READY=1" not in _recv(srv) and time.monotonic() < end:
            pass
        srv.settimeout(0.5)              # ten of its periods: nothing more after READY
        with pytest.raises(TimeoutError):
            while True:
                m = srv.recv(4096).decode()
                assert "EXTEND_TIMEOUT_USEC" not in m, m
    finally:
        srv.close()


def test_start_up_extension_is_bounded(tmp_path):
    """A start-up that never gets READY is extended for ``max_s`` at most (then
    TimeoutStartSec fails it as before)."""
    from rigd.service import notify

    path = str(tmp_path / "notify.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    notify._READY.clear()
    try:
        assert notify.extend_start_up(environ={"NOTIFY_SOCKET": path}, every_s=0.02,
                                      max_s=0.1)
        srv.settimeout(2.0)
        n = 0
        try:
            while True:
                srv.recv(4096)
                n += 1
        except TimeoutError:
            pass
        assert 1 <= n <= 10, n
    finally:
        srv.close()
