"""A command answered "failed" is never applied afterwards (issue 21: ``op 1000 4`` timed out
behind a blocked command, the operator pressed SAFE, and Ω = 1000 was applied 15 s later).

The real socket process and ``rigd ctl`` processes in front of a real lock-step loop whose
``controller.load`` blocks until the test opens a gate (as a load from a FIFO did): the
``op`` sent meanwhile times out, SAFE goes through the SAFE word, the gate opens — and
neither the load nor the ``op`` is ever applied; what is sent after a ``reset`` is."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

from daemon_helpers import PROCESS_S, RIGD

from rigd.controller import save_controller
from rigd.loop.loop import ControlLoop
from rigd.loop.safeword import word_path
from rigd.rigconfig import default_config
from rigd.service.bridge import SocketFrontend
from rigd.service.protocol import Dispatcher

sys.path.append(str(Path(__file__).resolve().parents[1] / "loop"))
from loop_helpers import make_plant  # noqa: E402


class GatedLoop(ControlLoop):
    """The real loop; ``load_controller`` waits for :attr:`gate` first, and every operating
    point the loop thread really applies is logged in :attr:`applied_ops`."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.gate = threading.Event()
        self.entered = threading.Event()
        self.applied_ops: list[float] = []

    def load_controller(self, path, **kw):
        self.entered.set()
        assert self.gate.wait(PROCESS_S), "gate never opened"
        return super().load_controller(path, **kw)

    def set_operating_point(self, omega_rpm, p_inj_bar, **kw):
        fast = self.fast
        prepare = fast.prepare_operating_point

        def logged(om, pi):
            swap = prepare(om, pi)

            def run():
                self.applied_ops.append(om)
                swap()
            return run
        fast.prepare_operating_point = logged
        try:
            return super().set_operating_point(omega_rpm, p_inj_bar, **kw)
        finally:
            fast.prepare_operating_point = prepare


def _ctl(sock, *args, timeout=10.0):
    return subprocess.run([RIGD, "ctl", "--socket", sock, "--timeout", str(timeout), *args],
                          capture_output=True, text=True, timeout=PROCESS_S)


def test_a_timed_out_op_is_never_applied_after_safe(tmp_path):
    sock = str(tmp_path / "rigd.sock")
    ctrl = tmp_path / "k.yaml"
    save_controller(ctrl, [[0.99]], [[0.001, 0.0]], [[1.0], [0.0]], [[0.0, 0.0], [0.0, 0.0]],
                    fs_hz=5000.0)
    cfg = default_config(clock={"mode": "lockstep", "batch_cycles": 50})
    loop = GatedLoop(cfg, make_plant())
    disp = Dispatcher(loop, info=lambda: {"pid": os.getpid()})

    def snapshot():
        return {"status": loop.status(), "timing": loop.timing(), "faults": loop.faults(),
                "info": {"pid": os.getpid()}, "experiment": None}

    fe = SocketFrontend(sock, 0o660, disp.handle_line, snapshot,
                        safe_generation=lambda: loop.safe_generation)
    with loop:
        loop.safe.attach_file(word_path(sock))
        fe.start()
        loop.start()                     # lock-step, continuously, in its own thread
        try:
            assert fe.ready.wait(PROCESS_S), "socket process did not come up"
            load = subprocess.Popen([RIGD, "ctl", "--socket", sock, "--timeout", "4", "load",
                                     str(ctrl)], stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True)
            assert loop.entered.wait(PROCESS_S)        # the worker is blocked in the load
            r = _ctl(sock, "op", "1000", "4", timeout=4.0)
            assert r.returncode == 2, r.stdout        # "failed" for the operator
            assert "dropped" in r.stderr or "no reply" in r.stderr, r.stderr
            r = _ctl(sock, "safe")
            assert r.returncode == 0 and "via the safe word" in r.stdout, r.stderr
            out, err = load.communicate(timeout=PROCESS_S)
            assert load.returncode == 2, out          # timed out too
            loop.gate.set()                           # the blocked load goes on now
            r = _ctl(sock, "reset", timeout=60.0)     # queued behind both: runs after them
            assert r.returncode == 0, r.stderr
            r = _ctl(sock, "op", "500", "4", timeout=60.0)
            assert r.returncode == 0, r.stderr
            assert loop.applied_ops == [500.0]        # never 1000
            assert loop.controller is None            # the timed-out load was dropped
            assert loop.wait_cycles(10, PROCESS_S) >= 10
            st = loop.status()
            assert st["fault"]["code"] == 0 and st["last_frame"]["omega_rpm"] == 500.0
        finally:
            loop.gate.set()
            fe.stop()
