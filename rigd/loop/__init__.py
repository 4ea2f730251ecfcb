"""The 5 kHz control loop: kernels, clocks, timing, supervisor faults, recorder, ControlLoop.

Lazy exports (importing this package does not load numba)::

    from rigd.loop import ControlLoop, SegmentResult, RecordSpec, build_loop, simulate_record
"""

from __future__ import annotations

_EXPORTS = {
    "ControlLoop": "rigd.loop.loop",
    "SegmentResult": "rigd.loop.run",
    "RecordSpec": "rigd.loop.recorder",
    "open_recording": "rigd.loop.recorder",
    "build_loop": "rigd.loop.app",
    "simulate_record": "rigd.loop.sim",
}


def __getattr__(name: str):
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'rigd.loop' has no attribute {name!r}")
