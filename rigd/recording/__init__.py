"""HDF5 recordings, written outside the loop's process (docs/ARCHITECTURE.md).

* :mod:`rigd.recording.h5sink` — ``H5Sink`` (an SWMR HDF5 file) and ``open_recording``;
* :mod:`rigd.recording.writer` — the writer process: consumes the loop's shared ring,
  writes the files, publishes its consumer index in the ring's header.

The loop's process spawns the writer by module name and never imports this package.
"""
