"""A ring that cannot be shared (memfd refused, e.g. a file-size limit below the ring's size)
costs only the live stream: the loop, the recorder and the control socket work, the daemon says
why at start, and ``stream.subscribe`` is refused with one line. It once died at start with a
traceback (``OSError: [Errno 27] File too large`` from ``ftruncate``)."""

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from daemon_helpers import PROCESS_S, Daemon, make_config

from rigd.service.client import ControlClient, ControlError

ROOT = Path(__file__).resolve().parents[2]
LIMIT = 1 << 20          # 1 MiB: far below the default ring (tens of MiB)


def _limit_fsize():
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_shared_ring_under_a_small_file_size_limit_is_private_and_says_why():
    code = """
import json
from rigd.loop.shared_ring import SharedRing
r = SharedRing(100_000, 40, fs=5000.0)
r.ring[-1, -1] = 7.0
r.publish(100_000)
print(json.dumps({"unshared": r.unshared, "handle": r.handle() is None,
                  "last": r.ring[-1, -1], "w": int(r.hdr[0])}))
"""
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120, preexec_fn=_limit_fsize, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert "File too large" in out["unshared"] and "RLIMIT_FSIZE" in out["unshared"]
    assert out["handle"] is True and out["last"] == 7.0 and out["w"] == 100_000


def test_daemon_under_a_small_file_size_limit_runs_and_refuses_only_the_stream(tmp_path):
    d = Daemon(tmp_path, make_config(tmp_path), preexec=_limit_fsize)
    try:
        d.wait_notify("READY=1")
        st = d.ctl_json("status")
        assert st["running"] and st["fault"]["code"] == 0
        with ControlClient(d.sock, timeout=PROCESS_S) as c:
            with pytest.raises(ControlError, match="shares no recording ring"):
                c.stream(rate_hz=50, points=8)
            assert c.call("ping")                          # the connection still serves
    finally:
        code, _ = d.stop()
    assert code == 0, d.log()
    log = (tmp_path / "daemon.err").read_text()
    assert "Traceback" not in log
    warn = [json.loads(x) for x in log.splitlines() if "live stream unavailable" in x]
    assert len(warn) == 1 and "File too large" in warn[0]["reason"]


def test_recording_without_a_shared_ring_is_refused_in_one_line(tmp_path):
    """The HDF5 writer is a process of its own and maps the ring: no shared ring, no
    recording — refused before the loop starts, one line naming why, exit 2."""
    rec = tmp_path / "rec.h5"
    p = subprocess.run([sys.executable, "-c",
                        "import sys; from rigd.cli import main; sys.exit(main())",
                        "run", "--config", "config/sim.yaml", "--lockstep", "--duration", "1",
                        "--record", str(rec)], capture_output=True, text=True,
                       timeout=PROCESS_S, preexec_fn=_limit_fsize, cwd=ROOT)
    assert p.returncode == 2, p.stderr
    last = p.stderr.strip().splitlines()[-1]
    assert last.startswith("rigd run: recording refused: cannot create the shared ring"), last
    assert "RLIMIT_FSIZE" in last and "Traceback" not in p.stderr
    assert not rec.exists()
