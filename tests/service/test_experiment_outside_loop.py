"""An experiment's bookkeeping runs in an experiment process, never in the loop's process.

A fresh interpreter (the loop's process: a lock-step loop on the simulated plant and the
daemon's :class:`~rigd.service.experiment_host.ExperimentHost`) runs a sweep of PRBS points
and a simulated impact; afterwards no ``rigd.experiments`` module (schemas, signals, runner,
manifests) and no YAML parser of an experiment was ever imported there, yet the run folder
holds every record and a complete manifest written by the experiment process.
"""

import json
import subprocess
import sys

from daemon_helpers import PROCESS_S

from rigd.data import load_record
from rigd.data.manifest import read_manifest

SCRIPT = r"""
import json, os, sys
from rigd.loop.app import build_loop
from rigd.rigconfig import default_config
from rigd.service.experiment_host import ExperimentHost

runs = sys.argv[1]
sweep = {"kind": "sweep", "name": "outside", "grid": {"omega_rpm": [0, 1000],
         "p_inj_bar": [4.0]}, "settle": {"hold_s": 0.02},
         "at_each": {"kind": "prbs", "amplitude_v": 0.3, "duration_s": 0.2,
                     "lead_in_s": 0.02, "seed": 1}}
impact = {"kind": "impact", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
          "trigger": "sim", "axis": "x", "peak_n": 5.0, "pulse_s": 0.001,
          "pre_s": 0.01, "post_s": 0.05, "repeats": 1, "controller": [False]}
out = {"pid": os.getpid()}
with build_loop(default_config(), clock="lockstep") as lp:
    host = ExperimentHost(lp, runs)
    for name, spec in (("sweep", sweep), ("impact", impact)):
        started = host.start(spec=spec, run_dir=os.path.join(runs, name))
        host.join(%(wait)s)
        out[name] = {"started": started, "status": host.status()}
    try:
        host.start(spec={"kind": "prbs", "amplitude_v": "lots"})
    except Exception as exc:
        out["bad"] = str(exc)
out["modules"] = sorted(m for m in sys.modules if m.startswith("rigd.experiments")
                        or m == "rigd.service.reader")
print(json.dumps(out, default=str))
"""


def test_experiments_run_outside_the_loops_process(tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    p = subprocess.run([sys.executable, "-c", SCRIPT % {"wait": PROCESS_S}, str(runs)],
                       capture_output=True, text=True, timeout=3 * PROCESS_S)
    assert p.returncode == 0, p.stderr[-3000:]
    out = json.loads(p.stdout.strip().splitlines()[-1])
    # nothing of the experiments' code ever ran in the loop's process
    assert out["modules"] == [], out["modules"]
    for name, n_files in (("sweep", 2), ("impact", 1)):
        st = out[name]["status"]
        assert st["state"] == "complete", st
        assert out[name]["started"]["run_dir"] == str(runs / name)
        man = read_manifest(runs / name)
        assert man["status"] == "complete" and len(man["files"]) == n_files, man
        for f in man["files"]:
            rec = load_record(runs / name / f["path"])
            assert rec.n == f["n_frames"] > 0
    imp = read_manifest(runs / "impact")["files"][0]
    rec = load_record(runs / "impact" / imp["path"])
    # the hammer blow crossed as data and was played at its cycle: the force is there
    assert abs(rec.col("f_x")).max() > 1.0
    # a spec refused in the experiment process is one line, and nothing was made
    assert "amplitude_v" in out["bad"] and "\n" not in out["bad"]
    assert sorted(x.name for x in runs.iterdir()) == ["impact", "sweep"]
    assert json.loads((runs / "sweep" / "manifest.json").read_text())["experiment"][
        "name"] == "outside"
