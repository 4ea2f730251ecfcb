"""The 5 kHz control loop: compiled cycle, clocks, timing, supervisor faults, recorder, ControlLoop.

Import from the module that defines a name (importing this package loads nothing)::

    from rigd.loop.app import build_loop
    from rigd.loop.loop import ControlLoop, SegmentResult
    from rigd.loop.sinks import RecordSpec
    from rigd.recording.h5sink import open_recording   # (not the loop's: it imports h5py)
    from rigd.loop.sim import simulate_record
"""
