"""The experiment process killed while its PRBS plays in the real daemon: ``rigd ctl
experiment`` says ``interrupted (process ended)`` and how it ended (no state left at
``running``: the daemon recovers the run at once, its record kept and listed), its excitation
ends when its process does (the 60 s PRBS does not play on for nobody: the kept record is
seconds long), the loop cycles on without a fault, and the next experiment runs to
``complete``."""

import json
import os
import signal
from pathlib import Path

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
        journal = Path(exp["run_dir"]) / "manifest.json"
        # the journal names the .part before the segment is asked for; the kill lands once
        # the daemon's writer has the file (killed in between, there is rightly no record)
        def part_on_disk():
            names = [p.get("recording") for p in json.loads(journal.read_text())["points"]]
            return any(n and (journal.parent / n).exists() for n in names)

        assert wait_for(part_on_disk, PROCESS_S)
        os.kill(exp["pid"], signal.SIGKILL)      # while its PRBS plays and is recorded
        # the segment is cancelled at the next cycle when its process ends, then said
        assert wait_for(lambda: d.ctl_json("experiment")["state"] != "running", PROCESS_S)
        assert wait_for(lambda: d.ctl_json("experiment")["state"] != "failed", PROCESS_S)
        exp = d.ctl_json("experiment")
        assert exp["state"] == "interrupted (process ended)", exp
        assert "killed by SIGKILL" in exp["message"] and "records kept" in exp["message"], exp
        man = json.loads((Path(exp["run_dir"]) / "manifest.json").read_text())
        kept = [f for f in man["files"] if f.get("complete") is False]
        assert kept and kept[0]["n_frames"] < 30 * 5000, man["files"]   # not the whole 60 s
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
