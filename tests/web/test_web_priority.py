"""``rigd web``'s event loop — the thread that reads the console's SAFE request — runs at
``SCHED_FIFO`` (``--rt-priority``, default 10) where the machine permits it, and nothing it
starts inherits that: its worker threads run at normal priority (rigd.web.priority). Checked
on a real ``rigd web`` process through /proc, against what its start line says."""

from __future__ import annotations

import os
import subprocess
import urllib.request
from pathlib import Path

from daemon_helpers import RIGD
from webproc import WebProcess

SCHED_OTHER, SCHED_FIFO = 0, 1


def _fifo_permitted() -> bool:
    """Can a process of this user take SCHED_FIFO 10? (tried in a child, which then exits)"""
    pid = os.fork()
    if pid == 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
        except OSError:
            os._exit(1)
        os._exit(0)
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) == 0


def _policies(pid: int) -> dict[int, tuple[int, int]]:
    """{thread id: (policy, real-time priority)} of every thread of ``pid`` (/proc stat
    fields 41 and 40)."""
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            stat = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
        except FileNotFoundError:              # a thread that just ended
            continue
        fields = stat.rsplit(")", 1)[1].split()
        out[int(tid)] = (int(fields[38]), int(fields[37]))
    return out


def _web(tmp_path: Path, **args) -> WebProcess:
    (tmp_path / "runs").mkdir(exist_ok=True)
    (tmp_path / "config").mkdir(exist_ok=True)
    # no daemon is needed to serve the page: the priority is taken before serving
    return WebProcess(tmp_path, str(tmp_path / "absent.sock"), tmp_path / "runs",
                      tmp_path / "config", args=args)


def test_event_loop_real_time_and_its_worker_threads_normal(tmp_path):
    web = _web(tmp_path)
    try:
        line = next(x for x in web.lines if "event loop" in x)
        # a request that runs in a worker thread (a file read), so that one exists
        with urllib.request.urlopen(web.url + "/", timeout=120) as r:
            assert r.status == 200
        pol = _policies(web.proc.pid)
        main = pol.pop(web.proc.pid)
        assert pol, "no other thread in rigd web"
        if _fifo_permitted():
            assert line.endswith("at SCHED_FIFO 10"), line
            assert main == (SCHED_FIFO, 10), main
        else:
            assert "normal priority (SCHED_FIFO 10 not permitted" in line, line
            assert main == (SCHED_OTHER, 0), main
        # every other thread (uvicorn's, the worker threads) at normal priority
        assert all(p == (SCHED_OTHER, 0) for p in pol.values()), pol
    finally:
        web.stop()


def test_rt_priority_zero_keeps_normal_priority(tmp_path):
    web = _web(tmp_path, **{"--rt-priority": "0"})
    try:
        line = next(x for x in web.lines if "event loop" in x)
        assert line.endswith("at normal priority (--rt-priority 0)"), line
        assert _policies(web.proc.pid)[web.proc.pid] == (SCHED_OTHER, 0)
    finally:
        web.stop()


def test_rt_priority_out_of_range_is_refused_in_one_line(tmp_path):
    for bad, why in (("99", "99 is outside 0-98"), ("ten", "'ten' is not an integer")):
        r = subprocess.run([RIGD, "web", "--rt-priority", bad, "--listen", "127.0.0.1:0"],
                           capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert r.returncode == 2, r
        last = r.stderr.strip().splitlines()[-1]
        assert "--rt-priority" in last and why in last, r.stderr
