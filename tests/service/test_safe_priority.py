"""`safe` never waits behind a slow command: the daemon side (SocketFrontend) spawning the real
socket process on a real Unix socket, a loop double whose ``controller.load`` blocks until the
test opens a gate. While that load is provably pending (blocked inside the double), `safe`
from another client is run and answered; the load is answered after the gate opens.
No timing: "pending" is a fact (the gate is closed)."""


import pytest
from fakeloop import GatedLoop, controller_beside, gated_frontend
from test_busy_socket import Conn

from rigd.loop import faults as FC
from rigd.service.client import controller_args


class TrippableLoop(GatedLoop):
    """The gated double with the loop's ``trip`` and a ``status`` fault as the loop has it."""

    def __init__(self):
        super().__init__()
        self.trips = []

    def trip(self, code):
        self._log("trip", code)
        self.trips.append(code)

    def status(self):
        st = super().status()
        code = self.trips[0] if self.trips else 0
        st["fault"] = {"code": code, "name": FC.fault_name(code), "text": "", "seq": 5}
        return st


@pytest.fixture()
def gated(tmp_path):
    loop = TrippableLoop()
    path = str(tmp_path / "rigd.sock")
    with gated_frontend(loop, path):
        yield path, loop


def test_safe_answered_while_a_slow_load_is_pending(gated):
    path, loop = gated
    a = Conn(path)
    a.send({"id": "load", "cmd": "controller.load", **controller_args(controller_beside(path))})
    assert loop.entered.wait(30), "the load did not reach the loop"
    b = Conn(path)
    try:
        r = b.ask({"id": 2, "cmd": "safe"})
        assert not loop.gate.is_set()            # the load is still blocked in the loop
        assert r["ok"] and r["result"]["fault"]["name"] == "operator_safe", r
        assert loop.trips == [FC.OPERATOR_SAFE]
        assert not a.has_reply()
        # status, answered from the snapshot the safe reply brought, says so too
        assert b.ask({"id": 3, "cmd": "status"})["result"]["fault"]["code"] == FC.OPERATOR_SAFE
        loop.gate.set()
        ra = a.reply()
        assert ra["id"] == "load" and ra["ok"], ra
        assert [c[0] for c in loop.calls] == ["trip", "load_controller"]
    finally:
        a.close()
        b.close()
