"""`rigd experiment` never falls back to the simulator (issue 16 item 3): a configured or
default socket that does not answer is one line and exit 2, nothing created; in-process runs
only with --lockstep/--config, and its records and manifest say `source: simulated`."""

import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from testpaths import ROOT

from rigd.data import load_record

RIGD = [sys.executable, "-c", "import sys; from rigd.cli import main; sys.exit(main())"]
EXP = ("kind: prbs\noperating_point: {omega_rpm: 0, p_inj_bar: 4}\namplitude_v: 1\n"
       "duration_s: 0.2\nlead_in_s: 0.05\n")


@pytest.fixture
def work(tmp_path):
    """A working directory with the shipped config/sim.yaml (what the old fall-back used)."""
    shutil.copytree(ROOT / "config", tmp_path / "config")
    (tmp_path / "e.yaml").write_text(EXP)
    return tmp_path


def _rigd(cwd, *args, env=None, timeout=60):
    e = {k: v for k, v in os.environ.items() if k != "RIGD_SOCKET"}
    e.update(env or {})
    return subprocess.run([*RIGD, *args], capture_output=True, text=True, cwd=cwd, env=e,
                          timeout=timeout)


def _refused(proc, cwd, sock, words):
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert sock in lines[0] and words in lines[0] and "--lockstep" in lines[0], lines[0]
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert not (cwd / "run").exists() and not (cwd / "runs").exists()   # nothing ran


def _dead_socket(path):
    """A socket file nobody listens on (the daemon died without removing it)."""
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.bind(str(path))
    s.close()
    assert os.path.exists(path)


def test_socket_file_without_listener(work):
    sock = str(work / "dead.sock")
    _dead_socket(sock)
    proc = _rigd(work, "experiment", "e.yaml", "--socket", sock, "--out", "run")
    _refused(proc, work, sock, "does not answer")


def test_default_socket_without_listener_is_not_replaced_by_the_simulator(work):
    sock = str(work / "dead.sock")
    _dead_socket(sock)
    proc = _rigd(work, "experiment", "e.yaml", "--out", "run", env={"RIGD_SOCKET": sock})
    _refused(proc, work, sock, "does not answer")


def test_missing_default_socket(work):
    sock = str(work / "nobody.sock")
    proc = _rigd(work, "experiment", "e.yaml", "--out", "run", env={"RIGD_SOCKET": sock})
    _refused(proc, work, sock, "no daemon socket")


def test_listener_that_never_answers(work):
    """A busy or hung daemon: the connection is queued, no reply ever comes."""
    sock = str(work / "hung.sock")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(sock)
    srv.listen(4)                      # never accept()ed, never answered
    try:
        proc = _rigd(work, "experiment", "e.yaml", "--socket", sock, "--timeout", "0.5",
                     "--out", "run")
    finally:
        srv.close()
    _refused(proc, work, sock, "no reply within 0.5 s")


@pytest.mark.skipif(os.geteuid() == 0 and not shutil.which("setpriv"),
                    reason="root connects to a mode-000 socket; no setpriv to drop its "
                           "permission-override capabilities")
def test_socket_without_permission():
    """A socket the user may not open (mode 000). As root the client keeps uid 0 but loses
    CAP_DAC_OVERRIDE/CAP_DAC_READ_SEARCH (setpriv), so the socket's mode applies to it while it
    still reads its own checkout and venv as their owner (dropping to nobody failed on a clone
    under a 0700 directory: 'No module named rigd')."""
    import tempfile

    d = Path(tempfile.mkdtemp(prefix="rigd-perm-"))
    try:
        d.chmod(0o755)
        (d / "e.yaml").write_text(EXP)
        (d / "e.yaml").chmod(0o644)
        sock = str(d / "locked.sock")
        srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        srv.bind(sock)
        srv.listen(4)
        os.chmod(sock, 0)
        cmd = [*RIGD, "experiment", "e.yaml", "--socket", sock, "--out", "run"]
        if os.geteuid() == 0:
            caps = "-dac_override,-dac_read_search"
            cmd = ["setpriv", f"--bounding-set={caps}", f"--inh-caps={caps}", *cmd]
        env = {k: v for k, v in os.environ.items() if k != "RIGD_SOCKET"}
        env["HOME"] = str(d)
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=d, env=env,
                                  timeout=60)
        finally:
            srv.close()
        _refused(proc, d, sock, "permission denied")
    finally:
        shutil.rmtree(d)


def test_socket_and_in_process_together_refused(work):
    proc = _rigd(work, "experiment", "e.yaml", "--socket", str(work / "x.sock"),
                 "--lockstep", "--out", "run")
    assert proc.returncode == 2 and "--socket" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and not (work / "run").exists()


def test_lockstep_in_process_says_simulated(work):
    """Asked for: in-process lock-step, even with a dead default socket around."""
    sock = str(work / "dead.sock")
    _dead_socket(sock)
    proc = _rigd(work, "experiment", "e.yaml", "--lockstep", "--out", "run",
                 env={"RIGD_SOCKET": sock}, timeout=120)
    assert proc.returncode == 0, proc.stderr
    man = json.loads((work / "run" / "manifest.json").read_text())
    assert man["status"] == "complete" and man["mode"] == "lockstep"
    assert man["source"] == "simulated" and man["drivers"] == {"fast": "sim", "slow": []}
    rec = load_record(work / "run" / man["files"][0]["path"])
    assert rec.meta["source"] == "simulated" and rec.meta["drivers"]["fast"] == "sim"
