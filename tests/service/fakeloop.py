"""A test double of the *loop* (rigd.loop.ControlLoop command API), not of service code."""

import contextlib
import os
import threading

from daemon_helpers import PROCESS_S

from rigd.errors import InputError


class FakeLoop:
    def __init__(self):
        self.lock = threading.Lock()
        self.calls = []
        self.enabled = False
        self.op = (0.0, 4.0)
        self.fault = 0

    def _log(self, *c):
        with self.lock:
            self.calls.append(c)

    def status(self):
        return {"running": True, "cycle": len(self.calls), "controller_enabled": self.enabled,
                "omega_rpm": self.op[0], "p_inj_bar": self.op[1], "fault": self.fault,
                "nan_field": float("nan")}

    def timing(self):
        return {"compute_us": {"p50": 1.0, "p99": 2.0, "p99.9": 3.0, "max": 4.0},
                "overruns": 0, "rt_miss_fraction": 0.0}

    def faults(self):
        return [{"code": 3, "name": "sensor_nan", "seq": 10, "latched": True}] if self.fault else []

    def trip(self, code):
        self._log("trip", code)
        self.fault = int(code)

    def reset_fault(self):
        self._log("reset_fault")
        self.fault = 0

    def enable_controller(self, on):
        self._log("enable_controller", on)
        self.enabled = bool(on)

    def load_controller(self, path):
        # a path (a Dispatcher reading files itself) or the Controller the socket process
        # read and packed (its source names the file)
        path = str(getattr(path, "source", path))
        self._log("load_controller", path)
        if not path.endswith(".yaml"):
            raise InputError("not a controller file", path)

    def set_operating_point(self, omega_rpm, p_inj_bar):
        self._log("set_operating_point", omega_rpm, p_inj_bar)
        if omega_rpm == 13.0:
            raise RuntimeError("boom")  # a bug in the loop: must become an error reply
        self.op = (omega_rpm, p_inj_bar)


class GatedLoop(FakeLoop):
    """A loop whose ``load_controller`` is slow: it blocks until the test opens :attr:`gate`
    (as a large controller being validated would), so a test can hold a forwarded command
    pending for as long as it needs — no sleeping, no timing."""

    def __init__(self):
        super().__init__()
        self.gate = threading.Event()
        self.entered = threading.Event()

    def load_controller(self, path):
        self.entered.set()
        if not self.gate.wait(60.0):
            raise RuntimeError("gate never opened")
        super().load_controller(path)


def controller_beside(sock_path: str) -> str:
    """A valid controller file ``k.yaml`` beside the socket (the socket process reads it)."""
    from rigd.controller import save_controller

    k = os.path.join(os.path.dirname(sock_path), "k.yaml")
    if not os.path.exists(k):
        save_controller(k, [[0.5]], [[0.0, 0.0]], [[0.0], [0.0]], [[0.0, 0.0], [0.0, 0.0]],
                        fs_hz=5000.0)
    return k


@contextlib.contextmanager
def gated_frontend(loop: GatedLoop, path: str):
    """The real socket process (rigd.service.bridge.SocketFrontend) on ``path`` with the real
    Dispatcher in front of ``loop``; yields once it serves, opens the gate and stops it after.
    A valid controller waits beside the socket (:func:`controller_beside`)."""
    from rigd.service.bridge import SocketFrontend
    from rigd.service.protocol import Dispatcher

    controller_beside(path)
    disp = Dispatcher(loop, info=lambda: {"pid": os.getpid()})

    def snapshot():
        return {"status": loop.status(), "timing": loop.timing(), "faults": loop.faults(),
                "info": {"pid": os.getpid()}, "experiment": None}

    fe = SocketFrontend(path, 0o660, disp.handle_line, snapshot).start()
    try:
        # a hang bound only: the socket process (niced +10) imports for seconds of CPU, which
        # took more than 60 s on the shared machine at load 25 (issue 21, under-load run 02)
        assert fe.ready.wait(PROCESS_S), "socket process did not come up"
        yield
    finally:
        loop.gate.set()
        fe.stop()
