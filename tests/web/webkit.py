"""Helpers of the web console's tests (import as ``from webkit import ...``: a unique name;
``from conftest import`` is ambiguous once several test folders have a conftest.py)."""

TOKEN = "t0ken-for-the-tests-0123456789"
READ_TOKEN = "read-0nly-t0ken-for-the-tests-0123"


class FakeExperiments:
    """Stands in for the daemon's experiment manager: records what it is asked to start."""

    def __init__(self):
        self.started = []

    def start(self, path=None, spec=None, run_dir=None):
        self.started.append(path)
        return {"run_dir": None, "name": "x", "kind": "prbs", "total": 1}

    def status(self):
        return {"state": "idle"}

    def stop(self):
        return {"stopping": False}


def auth(token=TOKEN):
    return {"Authorization": f"Bearer {token}"}
