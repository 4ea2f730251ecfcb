"""``rigd experiment`` in-process on the real-time clock (no daemon, no --lockstep), end to end.

It used to die: ``run_segment`` made the HDF5 sink, then (real-time clock, loop not started)
called itself and made a second sink on the same path while the first was open (OSError from
the settle check's ``.settle.h5``), leaving the run ``failed``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

from rigd.frame import REC
from rigd.recording.h5sink import open_recording

ROOT = Path(__file__).resolve().parents[2]
RIGD = "import sys; from rigd.cli import main; sys.exit(main())"


def test_prbs_experiment_in_process_realtime(tmp_path):
    cfg = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    # the shared test host's scheduling jitter is not what this test is about
    cfg["supervisor"]["overrun_storm_count"] = 10**9
    cfg.setdefault("clock", {})["spin_us"] = 0.0
    conf = tmp_path / "rig.yaml"
    conf.write_text(yaml.safe_dump(cfg, sort_keys=False))
    out = tmp_path / "run"
    env = {k: v for k, v in os.environ.items() if k != "RIGD_SOCKET"}
    proc = subprocess.run(
        [sys.executable, "-c", RIGD, "experiment", str(ROOT / "config/experiments/prbs.yaml"),
         "--config", str(conf), "--out", str(out)],
        capture_output=True, text=True, timeout=300, cwd=str(tmp_path), env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr
    man = json.loads((out / "manifest.json").read_text())
    assert man["status"] == "complete", man
    spec = yaml.safe_load((ROOT / "config/experiments/prbs.yaml").read_text())
    n_expected = round((spec["duration_s"] + spec["lead_in_s"]) * cfg["loop"]["fs_hz"])
    records = sorted(out.rglob("*.h5"))
    assert records, list(out.rglob("*"))
    with open_recording(records[0]) as f:
        fr = f["frames"][:]
    assert len(fr) >= n_expected
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1)           # contiguous: nothing dropped
    assert np.all(fr[:, REC["fault"]] == 0)
    assert np.any(fr[:, REC["x_x"]] != 0)                    # the PRBS was played
