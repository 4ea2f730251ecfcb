"""Fault-injection suite on real daemon processes: the service tests' helpers
(tests/service/daemon_helpers.py, faultkit.py, emuproc.py, modbus_server.py) importable."""

import sys

from testpaths import ROOT

for sub in ("tests/service", "tests"):
    p = str(ROOT / sub)
    if p not in sys.path:
        sys.path.insert(0, p)
