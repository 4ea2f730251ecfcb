"""What a client sends of its files is parsed and validated by the socket process, never by
the loop's process: the daemon's side (SocketFrontend + Dispatcher(reads_files=False)) runs
here, in the test process, with every file reader of this process made to fail — a ~0.7 MB
controller (read by its client, a process of its own) and an experiment still load, and
what arrives here is the packed result."""

import hashlib
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from bigcontroller import write_big_controller
from daemon_helpers import PROCESS_S
from fakeloop import FakeLoop

from rigd import bounded, configio
from rigd.service import reader


class _Experiments:
    def __init__(self):
        self.started = []

    def start(self, path=None, spec=None, run_dir=None, experiment=None):
        self.started.append((path, spec, run_dir, experiment))
        return {"run_dir": run_dir, "name": experiment["name"], "kind": experiment["kind"],
                "total": None}

    def status(self):
        return {"state": "idle"}

    def stop(self):
        return {"stopping": False}


def controller_args(path):
    """What ``rigd ctl load`` sends for ``path``: read by the client, a process of its own
    (this one is the loop's: its readers fail)."""
    code = ("import json, sys; from rigd.service.client import controller_args; "
            "print(json.dumps(controller_args(sys.argv[1])))")
    r = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                       text=True, timeout=PROCESS_S, check=True)
    return json.loads(r.stdout)


def _ask(path, req, timeout=120):
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout)
        s.connect(path)
        s.sendall(json.dumps(req).encode() + b"\n")
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            assert chunk, "closed"
            buf += chunk
    return json.loads(buf)


@pytest.fixture()
def daemon_side(tmp_path, monkeypatch):
    from rigd.service.bridge import SocketFrontend
    from rigd.service.protocol import Dispatcher

    def forbidden(*a, **kw):
        raise AssertionError("a file was read in the loop's process")

    # this process is the loop's: nothing here may read or parse a file a client names
    for mod, name in ((bounded, "read_regular"), (configio, "read_yaml"),
                      (reader, "read_controller"), (reader, "read_experiment")):
        monkeypatch.setattr(mod, name, forbidden)
    loop, exps = FakeLoop(), _Experiments()
    disp = Dispatcher(loop, exps, info=lambda: {"pid": os.getpid()}, reads_files=False)

    def snapshot():
        return {"status": loop.status(), "timing": loop.timing(), "faults": loop.faults(),
                "info": {"pid": os.getpid()}, "experiment": exps.status()}

    runs = tmp_path / "runs"
    runs.mkdir()
    got = []

    def handle(line, gen=None, deadline=None, payload=None):
        got.append(payload)
        return disp.handle_line(line, gen, deadline, payload)

    sock = str(tmp_path / "rigd.sock")
    fe = SocketFrontend(sock, 0o660, handle, snapshot, fs_hz=5000.0,
                        runs_root=str(runs)).start()
    try:
        assert fe.ready.wait(PROCESS_S), "socket process did not come up"   # a hang bound
        yield sock, loop, exps, got, runs, fe
    finally:
        fe.stop()


def test_a_big_controller_is_parsed_in_the_socket_process(daemon_side, tmp_path):
    sock, loop, _, got, _, fe = daemon_side
    k = tmp_path / "big.yaml"
    write_big_controller(k)
    assert os.path.getsize(k) > 700_000
    r = _ask(sock, {"id": 1, "cmd": "controller.load", **controller_args(str(k))})
    assert r == {"id": 1, "ok": True, "result": {"loaded": str(k)}}, r
    assert loop.calls == [("load_controller", str(k))]
    packed = got[0]
    # what crossed into this process: four float64 matrices, the rate and the file's name
    assert sorted(packed) == ["A", "B", "C", "D", "fs_hz", "source"]
    assert packed["A"].shape == (64, 64) and packed["A"].dtype == np.float64
    assert packed["fs_hz"] == 5000.0 and fe.pid != os.getpid()
    # a bad file is refused there, with one line naming it: nothing reaches this process
    bad = tmp_path / "bad.yaml"
    bad.write_text("rigd_controller: 1\nfs_hz: 4000.0\nA: [[0.5]]\nB: [[0, 0]]\n"
                   "C: [[0], [0]]\nD: [[0, 0], [0, 0]]\n")
    r = _ask(sock, {"id": 2, "cmd": "controller.load", **controller_args(str(bad))})
    assert not r["ok"] and str(bad) in r["error"] and "4000 Hz" in r["error"], r
    assert len(got) == 1 and len(loop.calls) == 1


def test_an_experiment_is_read_in_the_socket_process(daemon_side, tmp_path):
    sock, _, exps, got, runs, _ = daemon_side
    exp = tmp_path / "prbs.yaml"
    exp.write_text((Path(__file__).parents[2] / "config/experiments/prbs.yaml")
                   .read_text())
    # the client's read of its file: its text goes with its name
    r = _ask(sock, {"id": 1, "cmd": "experiment.start", "path": str(exp),
                    "text": exp.read_text(), "run_dir": str(runs / "a")})
    assert r["ok"], r
    (path, spec, run_dir, experiment), = exps.started
    # what crossed into this process: the validated spec as plain values (no model object:
    # this process never imports the experiment schemas) and its text's hash, for the manifest
    assert sorted(experiment) == ["kind", "name", "source", "spec", "spec_sha256"]
    assert run_dir == str(runs / "a") and experiment["spec"]["kind"] == "prbs"
    assert experiment["kind"] == "prbs"
    assert json.loads(json.dumps(experiment)) == experiment
    assert experiment["source"] == str(exp) and experiment["name"] == "prbs-w0-p4"
    assert experiment["spec_sha256"] == "sha256:" + hashlib.sha256(exp.read_bytes()).hexdigest()
    # a run folder outside the runs folder is refused before anything is read
    for bad in (str(tmp_path / "elsewhere"), str(runs / ".." / "x")):
        r = _ask(sock, {"id": 2, "cmd": "experiment.start", "path": str(exp),
                        "text": exp.read_text(), "run_dir": bad})
        assert not r["ok"] and "must be inside the runs folder" in r["error"], r
    assert len(exps.started) == 1 and len(got) == 1
