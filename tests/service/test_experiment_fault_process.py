"""`rigd ctl safe` during an experiment in the real daemon process: the experiment ends at once.

Before, the experiment stayed "running" until its segment's planned end (the rest of the
record in the safe state) and only then said "interrupted". Now the loop thread flags the
segment at the fault's cycle, the experiment thread closes the record there and ends the run
``failed`` with the fault named in ``rigd ctl experiment`` and the manifest; another
experiment is refused while the fault is latched and runs after a reset.
"""

import json

import numpy as np
import yaml
from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import wait_for

from rigd.data import load_record
from rigd.loop import faults as FC

FS = 5000.0
LONG = {"kind": "prbs", "name": "long-prbs", "operating_point": {"omega_rpm": 0,
                                                                  "p_inj_bar": 4.0},
        "amplitude_v": 0.3, "seed": 3, "duration_s": 60.0, "lead_in_s": 0.1}
SHORT = {**LONG, "name": "short-prbs", "duration_s": 0.3}


def test_safe_ends_the_experiment_at_once_and_the_next_one_runs(tmp_path):
    cfg = make_config(tmp_path, clock={"spin_us": 0.0})
    long_spec, short_spec = tmp_path / "long.yaml", tmp_path / "short.yaml"
    long_spec.write_text(yaml.safe_dump(LONG))
    short_spec.write_text(yaml.safe_dump(SHORT))
    # run folders inside the daemon's --runs-dir (daemon_helpers: tmp/runs): others are refused
    run, run2 = tmp_path / "runs" / "run", tmp_path / "runs" / "run2"
    d = Daemon(tmp_path, cfg)
    try:
        d.wait_notify("READY=1")
        d.ctl("start", str(long_spec), "--run-dir", str(run))
        # the PRBS record is playing (r = excitation while K∞ is off)
        assert wait_for(lambda: d.ctl_json("status")["last_frame"]["r_x"] != 0.0, PROCESS_S)
        safe = d.ctl_json("safe")["fault"]
        assert safe["name"] == "operator_safe"
        assert wait_for(lambda: d.ctl_json("experiment")["state"] != "running", PROCESS_S)
        exp = d.ctl_json("experiment")
        seq_after = d.ctl_json("status")["seq"]
        # refused while the fault is latched, one line naming it; nothing made
        r = d.ctl("start", str(short_spec), "--run-dir", str(run2), check=False)
        assert r.returncode != 0 and "operator_safe is latched" in r.stderr, r.stderr
        assert not run2.exists()
        d.ctl("reset")
        assert wait_for(lambda: d.ctl_json("status")["fault"]["code"] == 0, PROCESS_S)
        d.ctl("start", str(short_spec), "--run-dir", str(run2))
        assert wait_for(lambda: d.ctl_json("experiment")["state"] not in ("starting",
                                                                          "running"),
                        PROCESS_S)
        exp2 = d.ctl_json("experiment")
    finally:
        code, _ = d.stop()
    assert code == 0, d.log()

    assert exp["state"] == "failed", exp
    assert exp["fault"] == safe and "operator_safe" in exp["message"], exp
    man = json.loads((run / "manifest.json").read_text())
    assert man["status"] == "failed" and man["fault"] == safe
    (pt,) = man["points"]
    assert pt["status"] == "failed" and "operator_safe" in pt["error"]
    assert not list(run.rglob("*.part"))
    (f,) = man["files"]
    rec = load_record(run / f["path"])                  # closed and readable
    seq = rec.col("seq")
    assert rec.n == f["n_frames"] and np.all(np.diff(seq) == 1)
    # the record ends at the very cycle the fault latched in, the experiment ended long
    # before the segment's planned end
    assert seq[-1] == safe["seq"]
    fault = rec.col("fault")
    assert fault[-1] == FC.OPERATOR_SAFE and np.all(fault[:-1] == 0)
    assert np.any(rec.col("x_x")[:-1] != 0)
    planned = int((LONG["duration_s"] + LONG["lead_in_s"]) * FS)
    assert seq_after < seq[0] + planned

    assert exp2["state"] == "complete" and exp2.get("fault") is None, exp2
    man2 = json.loads((run2 / "manifest.json").read_text())
    assert man2["status"] == "complete" and man2["fault"] is None
