"""Records survive every end (fault injection on real daemon processes, real HDF5 files).

* kill -9 of the experiment process mid-segment: the daemon recovers the run at once;
* kill -9 of the daemon 10 s into a 30 s daemon-hosted PRBS: at the next start the run lists
  a readable record of >= 9 s and is not ``running``;
* kill -9 of the experiment process and the daemon together (what the end of a systemd unit
  does): the next start replays the run's journal (``interrupted (process ended)``, the
  record recovered and listed, ``rigd ctl experiment`` says so);
* the disk filling up during an experiment (a small tmpfs; RLIMIT_FSIZE where mounting is not
  permitted): the record keeps its frames up to the last flush and is listed, the fault list
  names ``recorder_overflow``, and status keeps saying the recording failed after a reset;
* ``rigd run --record X.h5`` on an existing X.h5: refused in one line, X.h5 byte-identical; a
  ``{start}`` pattern writes a new file at every start.

Each checks the frames on disk against the frames flushed before the fault, the manifest's
state and the fault list.
"""

import contextlib
import hashlib
import json
import os
import signal
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
import yaml
from daemon_helpers import PROCESS_S, RIGD, Daemon, make_config
from faultkit import read_frames, wait_for

from rigd.frame import REC
from rigd.loop import faults as FC
from rigd.recording.h5sink import open_recording

FS = 5000.0
ENDED = "interrupted (process ended)"

#: hang bound per test, s: the kill fixture starts three daemons one after the other (a
#: daemon's READY alone took minutes at load average 20 on the shared 2-core machine)
pytestmark = pytest.mark.timeout(3 * PROCESS_S)


def prbs(name, duration_s):
    return {"kind": "prbs", "name": name, "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
            "amplitude_v": 0.3, "seed": 3, "duration_s": duration_s, "lead_in_s": 0.1}


def _spec(tmp, name, duration_s):
    p = tmp / f"{name}.yaml"
    p.write_text(yaml.safe_dump(prbs(name, duration_s)))
    return p


def _manifest(run):
    return json.loads((run / "manifest.json").read_text())


def _flushed(run):
    """Frames readable now in the run's record being written (0 before its first flush)."""
    parts = list(run.glob("*.part"))
    if not parts:
        return 0
    try:
        with open_recording(parts[0]) as f:     # SWMR: the extent of its last flush
            return int(f["frames"].shape[0])
    except (OSError, KeyError):
        return 0


def _watch_flushed(run, seen, done):
    """Note the frames flushed to the run's record until ``done`` (what the
    writer had made safe before the fault, seen from outside), every 50 ms."""
    while not done.wait(0.05):
        seen.append(_flushed(run))


def _gone(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    # a zombie (our child not reaped yet) is gone too
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def _start_experiment(d, spec, run, at_frames):
    """Start ``spec`` into ``run``; wait until ``at_frames`` frames of its record are flushed,
    watching the run folder itself (a `rigd ctl` call takes seconds on a loaded machine: the
    record must not end meanwhile). Returns (experiment process pid: the manifest's owner,
    frames flushed then, the `rigd ctl start` process)."""
    ctl = subprocess.Popen([RIGD, "ctl", "--socket", d.sock, "start", str(spec), "--run-dir",
                            str(run)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True)
    assert wait_for(lambda: _flushed(run) >= at_frames or ctl.poll() not in (None, 0),
                    PROCESS_S), d.hang_report()
    n = _flushed(run)
    assert n >= at_frames, (ctl.communicate(timeout=PROCESS_S), d.log())
    return _manifest(run)["owner"]["pid"], n, ctl


def _dir(tmp, name):
    (tmp / name).mkdir()
    return tmp / name


def _kill_daemon(d):
    os.kill(d.proc.pid, signal.SIGKILL)
    code, _ = d.stop()
    assert code == -signal.SIGKILL


def _one_record(run):
    """The run's listed record: (manifest entry, frames read from it)."""
    man = _manifest(run)
    assert len(man["files"]) == 1, man
    f = man["files"][0]
    fr = read_frames(run / f["path"])
    assert np.all(np.diff(fr[:, REC["seq"]]) == 1), "contiguous frames"
    assert not list(run.glob("*.part")), "nothing left under a temporary name"
    return f, fr


@pytest.fixture(scope="module")
def kills(tmp_path_factory):
    """Three kill points on real daemons sharing one runs folder (see module docstring):
    what was seen before each kill and after, for the tests below."""
    tmp = tmp_path_factory.mktemp("kills")
    cfg = make_config(tmp, clock={"spin_us": 0.0}, recorder={"flush_interval_s": 0.2})
    runs = tmp / "runs"
    seen = {}
    # 1. the experiment process killed mid-segment; the daemon lives on
    a = Daemon(_dir(tmp, "a"), cfg, "--runs-dir", str(runs))
    try:
        a.wait_notify("READY=1")
        run = runs / "exp-killed"
        pid, seen["exp_before"], ctl = _start_experiment(
            a, _spec(tmp, "exp-killed", 20.0), run, int(1.0 * FS))
        os.kill(pid, signal.SIGKILL)
        assert ctl.wait(PROCESS_S) == 0
        assert wait_for(lambda: a.ctl_json("experiment")["state"] not in ("running",
                                                                          "failed"), PROCESS_S)
        seen["exp_state"] = a.ctl_json("experiment")
        seen["exp_faults"] = a.ctl_json("faults")
        # 2. the daemon killed 10 s into a 30 s PRBS
        run = runs / "daemon-killed"
        exp_pid, seen["daemon_before"], ctl = _start_experiment(
            a, _spec(tmp, "daemon-killed", 30.0), run, int(10.0 * FS))
        seen["daemon_before_s"] = seen["daemon_before"] / FS
    finally:
        _kill_daemon(a)
    ctl.wait(PROCESS_S)
    assert wait_for(lambda: _gone(exp_pid), PROCESS_S)   # it finishes its run, then ends
    # the next start
    b = Daemon(_dir(tmp, "b"), cfg, "--runs-dir", str(runs))
    try:
        b.wait_notify("READY=1")
        assert wait_for(lambda: _manifest(runs / "daemon-killed")["status"] != "running",
                        PROCESS_S)
        seen["next_status"] = b.ctl_json("status")
        seen["next_faults"] = b.ctl_json("faults")
        # 3. the experiment process and the daemon killed together
        run = runs / "both-killed"
        pid, seen["both_before"], ctl = _start_experiment(
            b, _spec(tmp, "both-killed", 20.0), run, int(2.0 * FS))
        # together: both stopped first, so that neither sees the other end (a daemon that
        # outlives its experiment process by a moment closes the run itself: right, but not
        # this case), then both killed
        os.kill(b.proc.pid, signal.SIGSTOP)
        os.kill(pid, signal.SIGSTOP)
        os.kill(pid, signal.SIGKILL)
    finally:
        _kill_daemon(b)
    ctl.wait(PROCESS_S)
    seen["journal_left"] = _manifest(runs / "both-killed")["status"]
    c = Daemon(_dir(tmp, "c"), cfg, "--runs-dir", str(runs))
    try:
        c.wait_notify("READY=1")
        assert wait_for(lambda: c.ctl_json("experiment").get("recovered"), PROCESS_S)
        seen["recovered"] = c.ctl_json("experiment")
        seen["recovered_human"] = c.ctl("experiment").stdout
    finally:
        code, _ = c.stop()
    assert code == 0, c.log()
    seen["runs"] = runs
    return seen


def test_experiment_process_killed_its_run_recovered_by_the_daemon(kills):
    st = kills["exp_state"]
    assert st["state"] == ENDED and "killed by SIGKILL" in st["message"], st
    run = kills["runs"] / "exp-killed"
    assert _manifest(run)["status"] == ENDED
    f, fr = _one_record(run)
    # the segment played on in the daemon: every frame flushed before the kill, and more
    assert len(fr) == f["n_frames"] >= kills["exp_before"]
    assert kills["exp_faults"]["faults"] == [] and np.all(fr[:, REC["fault"]] == 0)


def test_daemon_killed_10s_into_a_30s_prbs_next_start_lists_a_readable_record(kills):
    run = kills["runs"] / "daemon-killed"
    man = _manifest(run)
    assert man["status"] == ENDED, man["status"]
    assert "the daemon" in man["message"] or "ended" in man["message"], man["message"]
    f, fr = _one_record(run)
    assert f["complete"] is False and f["incomplete_reason"], f
    assert kills["daemon_before_s"] >= 10.0
    assert len(fr) == f["n_frames"] >= kills["daemon_before"] >= 9.0 * FS
    with open_recording(run / f["path"]) as h:
        assert not h.attrs["complete"] and h.attrs["n_frames"] == len(fr)
        assert h.attrs["incomplete_reason"]
    assert man["points"][0]["status"] == "missing" and man["missing"] == [0]
    # no fault was latched before the kill; the next start runs clean
    assert np.all(fr[:, REC["fault"]] == 0)
    assert kills["next_status"]["fault"]["code"] == 0 and kills["next_faults"]["faults"] == []


def test_both_killed_the_next_start_replays_the_journal(kills):
    assert kills["journal_left"] == "running"      # what the dead processes left
    run = kills["runs"] / "both-killed"
    man = _manifest(run)
    assert man["status"] == ENDED and man.get("recovered"), man
    f, fr = _one_record(run)
    assert f["complete"] is False and len(fr) == f["n_frames"] >= kills["both_before"], f
    assert np.all(fr[:, REC["fault"]] == 0)
    rec = kills["recovered"]
    assert rec["state"] == "idle"
    (r,) = [x for x in rec["recovered"] if x["run_dir"] == str(run)]
    assert r["status"] == ENDED and r["files"] == [f["path"]], r
    assert ENDED in kills["recovered_human"] and f["path"] in kills["recovered_human"]


@contextlib.contextmanager
def small_disk(path, size_mb):
    """A tmpfs of ``size_mb`` MiB mounted at ``path`` (None if mounting is not permitted)."""
    path.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(path)],
                       capture_output=True, text=True)
    try:
        yield path if r.returncode == 0 else None
    finally:
        if r.returncode == 0:
            subprocess.run(["umount", "-l", str(path)], capture_output=True)


def test_disk_full_during_an_experiment_keeps_and_lists_the_record(tmp_path):
    with small_disk(tmp_path / "disk", 6) as disk:
        runs = disk if disk is not None else tmp_path / "runs"
        cfg = make_config(tmp_path, clock={"spin_us": 0.0}, recorder={"flush_interval_s": 0.1})
        d = Daemon(tmp_path, cfg, "--runs-dir", str(runs), fsize_limit=disk is None)
        run = runs / "full"
        seen = [0]
        try:
            d.wait_notify("READY=1")
            if disk is None:          # no mount here: a file-size limit, as the writer sees it
                d.limit_fsize(3 * 1024 * 1024, d.writer_pid())
            done = threading.Event()
            watch = threading.Thread(target=_watch_flushed, args=(run, seen, done), daemon=True)
            watch.start()
            d.ctl("start", str(_spec(tmp_path, "full", 30.0)), "--run-dir", str(run))
            over = wait_for(lambda: d.ctl_json("experiment")["state"] not in (
                "starting", "running"), PROCESS_S)
            done.set()
            watch.join(PROCESS_S)
            assert over, d.hang_report()
            exp = d.ctl_json("experiment")
            st = d.ctl_json("status")
            faults = d.ctl_json("faults")
            d.ctl("reset")
            assert wait_for(lambda: d.ctl_json("status")["fault"]["code"] == 0, PROCESS_S)
            after_reset = d.ctl_json("status")
            human = d.ctl("status").stdout
        finally:
            code, _ = d.stop()
        assert code == 0, d.log()
        assert exp["state"] == "failed" and "recorder_overflow" in exp["message"], exp
        man = _manifest(run)
        assert man["status"] == "failed" and man["fault"]["name"] == "recorder_overflow"
        f, fr = _one_record(run)
        assert f["complete"] is False and "keeps every frame up to the last flush" in \
            f["incomplete_reason"], f
        # the frames on disk: all the writer flushed, at least all the test saw flushed
        assert len(fr) >= f["n_frames"] >= max(seen) > 0, (len(fr), f, max(seen))
        assert f"({f['n_frames']} frames" in f["incomplete_reason"]
        assert any(x["code"] == FC.RECORDER_OVERFLOW for x in faults["faults"]), faults
        assert st["recorder"]["state"] == "failed", st["recorder"]
        # a reset clears the fault, not what status says of the recording
        rec = after_reset["recorder"]
        assert rec["state"] == "failed" and rec["failure"]["path"].endswith(".part"), rec
        assert rec["failure"]["since"] and "recorder: FAILED since" in human, human


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_run_record_refuses_an_existing_file_and_a_pattern_makes_new_files(tmp_path):
    cfg = make_config(tmp_path, clock={"spin_us": 0.0})
    x = tmp_path / "X.h5"
    x.write_bytes(b"a record that must survive\n" * 1000)
    before, mtime = _sha(x), x.stat().st_mtime_ns
    r = subprocess.run([RIGD, "run", "--config", str(cfg), "--lockstep", "--duration", "0.1",
                        "--no-notify", "--socket", str(tmp_path / "s.sock"),
                        "--record", str(x)], capture_output=True, text=True, timeout=PROCESS_S,
                       cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "exists" in lines[0] and "never overwritten" in lines[0], lines
    assert _sha(x) == before and x.stat().st_mtime_ns == mtime
    made = []
    for _ in range(2):
        r = subprocess.run([RIGD, "run", "--config", str(cfg), "--lockstep", "--duration",
                            "0.1", "--no-notify", "--socket", str(tmp_path / "s.sock"),
                            "--record", str(tmp_path / "crash-{start}.h5")],
                           capture_output=True, text=True, timeout=PROCESS_S, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        line = [x for x in r.stdout.splitlines() if x.startswith("recorded ")][0]
        n, path = int(line.split()[1]), Path(line.split(" to ", 1)[1])
        made.append(path)
        assert path.name.startswith("crash-2") and len(read_frames(path)) == n >= 0.1 * FS
    assert made[0] != made[1] and all(p.exists() for p in made)
    assert _sha(x) == before
