"""The real daemon against hostile files and fields: `/dev/zero`, a FIFO with no writer and a
500 MB (sparse) file given to `rigd ctl load` and `rigd ctl start` are refused with one line
and exit 2 — the daemon's memory unchanged, the loop still cycling; a large valid controller
loads; run folders outside the runs folder and loosely typed fields are refused."""

import json
import os
import socket

from bigcontroller import write_big_controller
from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import wait_for

#: the daemon's anonymous memory may grow this much at most during the attacks, bytes
RSS_SLACK = 20 << 20


def _rss(pid: int) -> dict[str, int]:
    """VmRSS and its anonymous part, bytes, from /proc/PID/status. The anonymous part is
    where a file read without bound would go (13 GB for /dev/zero before); the shared part
    grows on its own while the recorder's ring (a memfd) fills for the first time."""
    out = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            k, _, v = line.partition(":")
            if k in ("VmRSS", "RssAnon"):
                out[k] = int(v.split()[0]) * 1024
    return out


def _ask(sock: str, req: dict) -> dict:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(PROCESS_S)
        s.connect(sock)
        s.sendall(json.dumps(req).encode() + b"\n")
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            assert chunk, "closed"
            buf += chunk
    return json.loads(buf)


def test_hostile_files_are_refused_in_one_line_without_memory_or_stall(tmp_path):
    fifo = tmp_path / "k.fifo"
    os.mkfifo(fifo)                       # nobody ever writes: an open for reading would block
    big = tmp_path / "big.yaml"
    with open(big, "wb") as f:
        f.truncate(500 << 20)             # 500 MB, sparse
    d = Daemon(tmp_path, make_config(tmp_path))
    try:
        d.wait_notify("READY=1")
        rss0 = _rss(d.proc.pid)
        seq0 = d.ctl_json("status")["seq"]
        for what in ("load", "start"):
            for path, problem in (("/dev/zero", "must be a regular file, this is a character "
                                                "device"),
                                  (str(fifo), "must be a regular file, this is a FIFO"),
                                  (str(big), "is 500 MiB, larger than the limit")):
                r = d.ctl("--timeout", "300", what, path, check=False)
                assert r.returncode == 2, (what, path, r.stdout, r.stderr)
                lines = r.stderr.strip().splitlines()
                assert len(lines) == 1 and path in lines[0] and problem in lines[0], r.stderr
        rss1 = _rss(d.proc.pid)
        assert rss1["RssAnon"] - rss0["RssAnon"] < RSS_SLACK, (rss0, rss1)
        # the loop kept cycling, with no fault
        assert wait_for(lambda: d.ctl_json("status")["seq"] > seq0, PROCESS_S)
        st = d.ctl_json("status")
        assert st["running"] and st["fault"]["code"] == 0, st
        # and a large valid controller (~0.7 MB of YAML) loads
        k = tmp_path / "k_big.yaml"
        write_big_controller(k)
        d.ctl("--timeout", str(PROCESS_S), "load", str(k))
        st = d.ctl_json("status")["controller"]
        assert st["source"] == str(k) and st["order"] == 64, st
    finally:
        d.stop()


def test_run_dirs_and_field_types_are_refused(tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "out").symlink_to(tmp_path)         # a symlink in the runs folder pointing out
    exp = tmp_path / "prbs.yaml"
    exp.write_text("kind: prbs\n")
    d = Daemon(tmp_path, make_config(tmp_path))
    try:
        d.wait_notify("READY=1")
        for bad in (tmp_path / "elsewhere", runs / "out" / "x", runs / ".." / "y", "/tmp"):
            r = d.ctl("start", str(exp), "--run-dir", str(bad), check=False)
            assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
            assert "run_dir: must be inside the runs folder" in r.stderr, r.stderr
        assert not (tmp_path / "elsewhere").exists() and not (tmp_path / "x").exists()
        op0 = d.ctl_json("status")["last_frame"]["omega_rpm"]
        for field, value in (("omega_rpm", "3000"), ("omega_rpm", True),
                             ("p_inj_bar", "4"), ("p_inj_bar", False)):
            req = {"id": 9, "cmd": "operating_point.set", "omega_rpm": 1000.0,
                   "p_inj_bar": 4.0, field: value}
            r = _ask(d.sock, req)
            assert r["ok"] is False and r["error"].startswith(
                f"operating_point.set: {field}: "), r
        deep = {"id": 10, "cmd": "ping"}
        for _ in range(40):
            deep = {"x": deep}
        r = _ask(d.sock, {"id": 11, "cmd": "ping", "x": deep})
        assert r["ok"] is False and "deeper than" in r["error"], r
        st = d.ctl_json("status")
        assert st["last_frame"]["omega_rpm"] == op0 and st["fault"]["code"] == 0
    finally:
        d.stop()
