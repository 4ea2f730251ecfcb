"""``rigd run`` end to end, and the real-time clock."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from loop_helpers import make_plant

from rigd.frame import REC
from rigd.loop.loop import ControlLoop
from rigd.recording.h5sink import open_recording
from rigd.rigconfig import default_config

ROOT = Path(__file__).resolve().parents[2]
RIGD = [sys.executable, "-c", "import sys; from rigd.cli import main; sys.exit(main())"]
#: hang bound for a `rigd` subprocess, s: a 1 s lock-step run took 375 s of wall time (19.5 s
#: of CPU, mostly imports) on the shared 2-core machine at load average 25; 120 s timed out
PROCESS_S = 600


def test_rigd_run_lockstep_one_second_subprocess(tmp_path):
    rec = tmp_path / "run.h5"
    p = subprocess.run([*RIGD, "run", "--config", "config/sim.yaml", "--lockstep",
                        "--duration", "1", "--record", str(rec), "--json"],
                       cwd=ROOT, capture_output=True, text=True, timeout=PROCESS_S)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["timing"]["clock"] == "lockstep" and out["timing"]["cycles"] == 5000
    assert out["faults"] == []
    with open_recording(rec) as f:
        seq = f["frames"][:, REC["seq"]]
        assert f.attrs["p_inj_bar"] == 4.0
    assert len(seq) == 5000 and np.all(np.diff(seq) == 1)


def test_rigd_run_bad_config_subprocess_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((ROOT / "config" / "sim.yaml").read_text().replace("stale_frames: 3",
                                                                       "stale_frames: many"))
    p = subprocess.run([*RIGD, "run", "--config", str(bad), "--lockstep", "--duration", "1"],
                       cwd=ROOT, capture_output=True, text=True, timeout=PROCESS_S)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "supervisor.stale_frames" in lines[0] and f"{bad}:" in lines[0]


def test_rigd_run_record_where_no_file_can_be_made_one_line(tmp_path):
    """The writer process cannot create the file (its folder is a file): one line, exit 2."""
    (tmp_path / "plain").write_text("x")
    rec = tmp_path / "plain" / "run.h5"
    p = subprocess.run([*RIGD, "run", "--config", "config/sim.yaml", "--lockstep",
                        "--duration", "1", "--record", str(rec)],
                       cwd=ROOT, capture_output=True, text=True, timeout=PROCESS_S)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert lines[-1] == (f"rigd run: recording {rec}: cannot create it: File exists "
                         f"(errno 17)"), lines
    assert "Traceback" not in p.stderr


def _periods_bracket(loop, run):
    """Start ``loop`` (real-time clock), call ``run()`` while it runs, then stop it; returns
    ``(low, high)``, the wall-time bounds, s, that the periods the loop accounted for
    (``cycles + skipped_periods``, divided by ``fs``) must lie within — whatever the
    scheduler did.

    The clock's contract: every period from the loop's first deadline to its last cycle is
    a cycle or a skipped period (overrun ``skip``), or a cycle run late (``catch_up``). From
    outside: the loop started after ``t_before`` and before ``start()`` returned (``t0``);
    its last cycle ended before ``stop()`` returned (``t_after``) and after ``t_seen`` (a
    time after which two more cycles were seen to run). A ``catch_up`` loop may be behind
    by at most its largest lateness when it stops.
    """
    t_before = time.perf_counter()
    loop.start()
    t0 = time.perf_counter()
    run()
    t_seen = time.perf_counter()
    assert loop.wait_cycles(2, PROCESS_S) >= 2
    loop.stop()
    t_after = time.perf_counter()
    t = loop.timing()
    behind = t["lateness_us"]["max"] * 1e-6 if loop.config.clock.overrun == "catch_up" else 0.0
    return t_seen - t0 - behind - 1.0 / loop.fs, t_after - t_before


def test_realtime_clock_runs_at_rate_with_timing_and_recording(tmp_path):
    cfg = default_config(clock={"mode": "realtime"})
    loop = ControlLoop(cfg, make_plant())
    mid = {}
    with loop:
        sink = loop.start_recording(tmp_path / "rt.h5")

        def run():
            assert loop.wait_cycles(2500, PROCESS_S) >= 2500
            mid.update(loop.timing())              # available while running

        low, high = _periods_bracket(loop, run)
        loop.stop_recording(sink)
    t = loop.timing()
    assert mid["cycles"] > 0 and mid["compute_us"]["p50"] > 0
    assert t["clock"] == "realtime"
    # cycles + skipped periods account for the wall time at 5 kHz (bounds: _periods_bracket)
    assert low <= (t["cycles"] + t["skipped_periods"]) / 5000.0 <= high, (low, high, t)
    for k in ("p50", "p99", "p999", "max"):
        assert t["lateness_us"][k] >= 0 and t["compute_us"][k] > 0
    with open_recording(tmp_path / "rt.h5") as f:
        seq = f["frames"][:, REC["seq"]]
    # every cycle recorded, in order (the recording is of cycles, not of periods)
    assert len(seq) == t["cycles"] and np.all(np.diff(seq) == 1)


class _Hiccup:
    """Wraps the plant: one write at cycle ``at`` takes ``pause_s`` (a stalled driver)."""

    def __new__(cls, plant, at, pause_s):
        from loop_helpers import InjectingDriver

        drv = InjectingDriver(plant)
        orig = drv.write

        def write(drive):
            if drv.n == at:
                time.sleep(pause_s)
            orig(drive)
        drv.write = write
        return drv


def _rt_run(policy, cycles=3000):
    """A real-time loop whose driver stalls 4 ms (20 periods) at cycle 500, run until
    ``cycles`` cycles; returns its timing and the bounds of ``_periods_bracket``."""
    cfg = default_config(clock={"mode": "realtime", "overrun": policy})
    loop = ControlLoop(cfg, _Hiccup(make_plant(), 500, 0.004))   # 20 periods lost

    def run():
        assert loop.wait_cycles(cycles, PROCESS_S) >= cycles

    with loop:
        bounds = _periods_bracket(loop, run)
    return loop.timing(), bounds


def test_overrun_policy_skip_and_catch_up():
    skip, (low, high) = _rt_run("skip")
    assert skip["overruns"] >= 1 and skip["skipped_periods"] >= 19
    assert low <= (skip["cycles"] + skip["skipped_periods"]) / 5000.0 <= high
    catch, (low, high) = _rt_run("catch_up")
    assert catch["overruns"] >= 1 and catch["skipped_periods"] == 0
    assert catch["lateness_us"]["max"] >= 3500        # the missed cycles ran late, none skipped
    assert low <= catch["cycles"] / 5000.0 <= high    # every period ran, late or not
