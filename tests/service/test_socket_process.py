"""The control socket is served by a separate, spawned process (rigd.service.frontend): the
daemon's loop process never sees a malformed request, and the socket process dying is
survived — respawned, the socket answers again, the loop keeps cycling without a fault."""

import json
import os
import signal
import socket

from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import wait_for


def _ask(path, line):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(PROCESS_S)
    s.connect(path)
    s.sendall(line + b"\n")
    buf = b""
    while not buf.endswith(b"\n"):
        chunk = s.recv(65536)
        if not chunk:
            break
        buf += chunk
    s.close()
    return json.loads(buf)


def test_socket_process_separate_and_respawned(tmp_path):
    d = Daemon(tmp_path, make_config(tmp_path, clock={"spin_us": 0.0}))
    try:
        d.wait_notify("READY=1")
        ping = d.ctl_json("ping")
        assert ping["pid"] == d.proc.pid
        child = ping["socket_pid"]
        assert child != d.proc.pid
        # the socket file belongs to the daemon: mode 0660 while served by the child
        assert os.stat(d.sock).st_mode & 0o777 == 0o660
        # refused in the socket process, with the same messages as before
        r = _ask(d.sock, b'{"id": 3, "cmd": "controller.load", "path": "rel.yaml"}')
        assert r == {"id": 3, "ok": False, "error": "controller.load: path: must be an "
                     "absolute path (got 'rel.yaml')"}
        r = _ask(d.sock, b'{"id": 4, "cmd": "experiment.start", "path": "/x.yaml", '
                         b'"run_dir": "runs"}')
        assert r["ok"] is False and "run_dir: must be an absolute path" in r["error"]
        assert d.ctl_json("ping")["commands_run"] == ping["commands_run"], \
            "refused requests never reached the loop's process"
        # a valid command still goes through to the loop, and the next status shows it
        d.ctl("op", "1500", "4.0")
        assert d.ctl_json("ping")["commands_run"] == ping["commands_run"] + 1
        assert wait_for(lambda: d.ctl_json("status")["last_frame"]["omega_rpm"] == 1500.0,
                        PROCESS_S)
        seq0 = d.ctl_json("status")["seq"]
        # kill the socket process: the daemon starts a new one; nothing else changes
        os.kill(child, signal.SIGKILL)
        assert wait_for(lambda: "socket process died" in d.log(), PROCESS_S), d.log()
        assert wait_for(lambda: _ask(d.sock, b'{"cmd": "ping"}').get("ok") is True, PROCESS_S)
        ping2 = d.ctl_json("ping")
        assert ping2["socket_pid"] not in (child, d.proc.pid) and ping2["pid"] == d.proc.pid
        # not real-time and niced, although respawned by a real-time helper thread
        assert os.sched_getscheduler(ping2["socket_pid"]) == os.SCHED_OTHER
        assert os.getpriority(os.PRIO_PROCESS, ping2["socket_pid"]) >= 10
        st = d.ctl_json("status")
        assert st["running"] and st["seq"] > seq0 and st["fault"]["code"] == 0
        assert d.proc.poll() is None
    finally:
        code, _ = d.stop(signal.SIGTERM)
    assert code == 0, d.log()
    assert not os.path.exists(d.sock), "socket file removed on exit"


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie (exited, not yet reaped by init) counts as gone
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_sigkilled_daemon_leaves_no_socket_process_and_a_new_daemon_starts(tmp_path):
    cfg = make_config(tmp_path, clock={"spin_us": 0.0})
    d = Daemon(tmp_path, cfg)
    try:
        d.wait_notify("READY=1")
        child = d.ctl_json("ping")["socket_pid"]
    finally:
        code, _ = d.stop(signal.SIGKILL)
    assert code == -signal.SIGKILL
    # the socket process sees its pipe close and exits; the socket file stays behind, stale
    assert wait_for(lambda: not _alive(child), PROCESS_S), "socket process outlived the daemon"
    assert os.path.exists(d.sock)
    os.unlink(tmp_path / "notify.sock")   # the test's own notify socket, not the daemon's
    d2 = Daemon(tmp_path, cfg)            # same control socket path: the stale file is replaced
    try:
        d2.wait_notify("READY=1")
        assert d2.ctl_json("ping")["pid"] == d2.proc.pid
    finally:
        code, _ = d2.stop(signal.SIGTERM)
    assert code == 0, d2.log()
