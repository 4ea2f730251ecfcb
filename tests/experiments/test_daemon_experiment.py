"""`rigd experiment --socket` against a real daemon process (`rigd run`), on the real-time clock."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from testpaths import ROOT

from rigd.data.io import load_record

RIGD = str(Path(sys.executable).parent / "rigd")

EXPERIMENT = """\
kind: prbs
name: daemon-prbs
operating_point: {omega_rpm: 0, p_inj_bar: 4.0}
amplitude_v: 0.5
switch_probability: 0.5
min_hold_s: 0.001
seed: 7
duration_s: 0.6
lead_in_s: 0.1
"""


def _config(tmp_path):
    cfg = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    # the shared 2-core test host has scheduling jitter; overrun storms have their own test
    cfg["supervisor"]["overrun_storm_count"] = 10**9
    cfg["recorder"]["data_dir"] = str(tmp_path / "data")
    path = tmp_path / "sim.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def _wait_ping(sock, proc, timeout=600.0):
    # a hang bound, as daemon_helpers.PROCESS_S: at load 30 the daemon's socket process
    # (spawned, niced) took more than 60 s to serve
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        assert proc.poll() is None, proc.stderr.read().decode()
        if os.path.exists(sock):
            r = subprocess.run([RIGD, "ctl", "--socket", sock, "ping", "--json"],
                               capture_output=True, text=True)
            if r.returncode == 0:
                return json.loads(r.stdout)
        time.sleep(0.2)
    raise AssertionError("daemon did not come up")


def test_experiment_runs_inside_the_daemon(tmp_path):
    sock = str(tmp_path / "rigd.sock")
    proc = subprocess.Popen([RIGD, "run", "--config", str(_config(tmp_path)), "--socket", sock,
                             "--no-notify", "--runs-dir", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _wait_ping(sock, proc)
        exp = tmp_path / "prbs.yaml"
        exp.write_text(EXPERIMENT)
        out = tmp_path / "run"
        r = subprocess.run([RIGD, "experiment", str(exp), "--socket", sock, "--out", str(out)],
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr

        man = json.loads((out / "manifest.json").read_text())
        assert man["status"] == "complete"
        # played by the daemon's loop thread, not in-process lock-step
        assert man["mode"] == "realtime"
        assert man["source"] == "simulated" and man["drivers"] == {"fast": "sim", "slow": []}
        files = man["files"]
        assert len(files) == 1 and files[0]["kind"] == "prbs"
        rec = load_record(out / files[0]["path"])
        # every cycle of the request is there, in order, and the excitation is the PRBS asked
        assert rec.n == files[0]["n_frames"] >= int(0.7 * 5000)
        assert np.all(np.diff(rec.col("seq")) == 1)
        x = rec.col("x_x")
        assert set(np.unique(np.round(x[x != 0], 9))) == {-0.5, 0.5}
        assert rec.p_inj_bar == 4.0
        assert rec.meta["source"] == "simulated" and rec.meta["drivers"]["fast"] == "sim"

        # a bad experiment file is refused by the client before the daemon sees it
        bad = tmp_path / "bad.yaml"
        bad.write_text(EXPERIMENT.replace("duration_s: 0.6", "duration_s: -1"))
        r = subprocess.run([RIGD, "experiment", str(bad), "--socket", sock,
                            "--out", str(tmp_path / "run2")], capture_output=True, text=True)
        assert r.returncode == 2
        assert len(r.stderr.strip().splitlines()) == 1 and "duration_s" in r.stderr
        assert "Traceback" not in r.stderr
        assert not (tmp_path / "run2").exists()

        # the same from Python (rigd.api), progress reported, the manifest says its source
        from rigd.api import run_experiment_daemon

        seen = []
        res = run_experiment_daemon(exp, socket=sock, out=tmp_path / "run3",
                                    progress=lambda d, t, s: seen.append((d, t)))
        assert res.ok and res.mode == "daemon" and seen and seen[-1][1] >= 1
        man3 = res.read_manifest()
        assert man3["mode"] == "realtime" and man3["source"] == "simulated"
        assert len(man3["files"]) == 1 and (tmp_path / "run3" / man3["files"][0]["path"]).exists()
        # the daemon is still alive and well
        assert proc.poll() is None
    finally:
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(30)
    assert code == 0
