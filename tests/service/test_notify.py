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
