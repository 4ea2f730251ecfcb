"""The experiment process killed while its PRBS plays in the real daemon: ``rigd ctl
experiment`` says ``interrupted (process ended)`` and how it ended (no state left at
``running``: the daemon recovers the run at once, its record kept and listed), the loop cycles
on without a fault, and the next experiment runs to ``complete``."""

import os
import signal

import yaml
from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import wait_for

PRBS = {"kind": "prbs", "name": "killed-prbs", "operating_point": {"omega_rpm": 0,
                                                                    "p_inj_bar": 4.0},
        "amplitude_v": 0.3, "seed": 3, "duration_s": 60.0, "lead_in_s": 0.1}
SHORT = {**PRBS, "name": "after-prbs", "duration_s": 0.3}


def test_a_killed_experiment_process_fails_the_experiment_and_the_loop_cycles_on(tmp_path):
    spec, short = tmp_path / "prbs.yaml", tmp_path / "short.yaml"
    spec.write_text(yaml.safe_dump(PRBS))
    short.write_text(yaml.safe_dump(SHORT))
    d = Daemon(tmp_path, make_config(tmp_path, clock={"spin_us": 0.0}))
    try:
        d.wait_notify("READY=1")
        d.ctl("start", str(spec))
        assert wait_for(lambda: d.ctl_json("experiment")["state"] != "starting", PROCESS_S)
        exp = d.ctl_json("experiment")
        assert exp["state"] == "running", exp
        os.kill(exp["pid"], signal.SIGKILL)
        # bounded by the segment playing when it died (60 s at most), then said
        assert wait_for(lambda: d.ctl_json("experiment")["state"] != "running", PROCESS_S)
        assert wait_for(lambda: d.ctl_json("experiment")["state"] != "failed", PROCESS_S)
        exp = d.ctl_json("experiment")
        assert exp["state"] == "interrupted (process ended)", exp
        assert "killed by SIGKILL" in exp["message"] and "records kept" in exp["message"], exp
        st = d.ctl_json("status")
        assert st["running"] and st["fault"]["code"] == 0, st
        seq = st["seq"]
        assert wait_for(lambda: d.ctl_json("status")["seq"] > seq, PROCESS_S)
        d.ctl("start", str(short))
        assert wait_for(lambda: d.ctl_json("experiment")["state"] not in ("starting",
                                                                          "running"), PROCESS_S)
        exp = d.ctl_json("experiment")
        assert exp["state"] == "complete" and exp["name"] == "after-prbs", exp
    finally:
        d.stop()
    assert d.proc.returncode == 0, d.log()
