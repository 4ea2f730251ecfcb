"""Recording sinks: where the recorder puts frames and events.

:class:`Sink` (a destination of a contiguous sequence range), :class:`MemorySink` (frames in
memory, consumed in the loop's process), :class:`FileSink` (an HDF5 file written by the
**writer process**, :mod:`rigd.recording.writer`: this is its proxy in the loop's process,
holding the file's name, metadata and sequence range, the latter mirrored into the shared
ring's sink slots), :class:`RecordSpec` (where and with which metadata a loop records).
Used by :class:`rigd.loop.recorder.Recorder`. Nothing here imports h5py: the loop's process
never does (import contract); read a recording with :func:`rigd.recording.h5sink.open_recording`.
"""

from __future__ import annotations

import os
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigd.frame import N_REC
from rigd.loop.shared_ring import H_SINKS, OPEN_END

EVENT_TEXT_LEN = 120


@dataclass
class RecordSpec:
    """Where and with which metadata to record (``run_segment(record=...)``).

    ``meta`` goes into the file's root attributes (``kind``, ``experiment``, ``omega_rpm``...).
    """

    path: str | Path
    meta: dict[str, Any] = field(default_factory=dict)


def reason(exc: BaseException) -> str:
    """Short reason of a failed write: the OS error text when it can be found."""
    errno_ = getattr(exc, "errno", None)
    if not isinstance(errno_, int):
        m = re.search(r"errno = (\d+)", str(exc))
        errno_ = int(m.group(1)) if m else None
    if isinstance(errno_, int) and errno_ > 0:
        return f"{os.strerror(errno_)} (errno {errno_})"
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:200]


def file_failure(sink: Sink, why: str) -> str:
    """One line: recording ``sink.path`` failed, ``why``, and what the file keeps (the frames
    up to its last flush, ``sink.n_flushed`` from ``sink.first_seq``)."""
    n = sink.n_flushed
    kept = (f"the file keeps every frame up to the last flush ({n} frames, seq "
            f"{sink.first_seq}..{sink.first_seq + n - 1})" if n and sink.first_seq is not None
            else "no frame had been flushed to it")
    return (f"recording {sink.path} failed: {why}; {kept}, readable with "
            f"rigd.recording.h5sink.open_recording (h5py swmr=True)")


class Sink:
    """Destination of a contiguous range of frames ``[first_seq, last_seq]`` (inclusive).

    ``first_seq`` may be set later (by the loop thread, at the cycle boundary where recording
    starts); ``last_seq`` None means open-ended until :meth:`Recorder.finish`.
    """

    def __init__(self) -> None:
        self.first_seq: int | None = None
        self.last_seq: int | None = None
        self.n_written = 0
        self.error: BaseException | None = None
        self.done = threading.Event()
        self.closing = False
        self.last_written_seq: int | None = None
        self.n_flushed = 0                 # frames safely on disk (at the last good flush)

    def describe_failure(self, exc: BaseException) -> str:
        """One line: what failed and what the destination still holds."""
        return f"recording failed: {reason(exc)}"

    # called by the writer thread only
    def write(self, block: np.ndarray) -> None:
        raise NotImplementedError

    def event(self, seq: int, code: int, text: str) -> None:
        pass

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass

    def abandon(self) -> None:
        """Give up after a failed write: keep what is on disk, never write again."""


class MemorySink(Sink):
    """Frames kept in memory (for :func:`rigd.loop.sim.simulate_record`)."""

    def __init__(self, n_expected: int = 0) -> None:
        super().__init__()
        self._buf = np.empty((max(n_expected, 1), N_REC))
        self.events: list[tuple[int, int, str]] = []

    def write(self, block: np.ndarray) -> None:
        n = self.n_written + len(block)
        if n > len(self._buf):
            new = np.empty((max(n, 2 * len(self._buf)), N_REC))
            new[:self.n_written] = self._buf[:self.n_written]
            self._buf = new
        self._buf[self.n_written:n] = block
        self.n_written = n

    def event(self, seq: int, code: int, text: str) -> None:
        self.events.append((seq, code, text))

    @property
    def frames(self) -> np.ndarray:
        return self._buf[:self.n_written]


class FileSink(Sink):
    """An HDF5 recording written by the writer process; its proxy in the loop's process.

    ``first_seq`` and ``last_seq`` are mirrored into the shared ring's sink slot once the
    recorder has given it one (:meth:`attach`): the loop thread sets ``first_seq`` at the
    segment's first cycle, before that cycle's frame is published, so the writer process
    (which reads the published count before the slots) never misses a frame of the range.
    ``n_written``, ``n_flushed`` and ``error`` come back from the writer process.
    """

    def __init__(self, path: str | Path, *, fs: float, meta: dict[str, Any] | None = None,
                 config_text: str = "", chunk_frames: int = 4096, n_expected: int = 0) -> None:
        self._hdr = None
        self._slot = -1
        super().__init__()
        self.path = Path(path)
        self.fs = float(fs)
        self.meta = dict(meta or {})
        self.config_text = config_text
        self.chunk_frames = int(chunk_frames)
        #: frames the recording should hold (a segment's length; 0: open-ended): a file
        #: closed with fewer is marked incomplete (``complete`` false) by the writer
        self.n_expected = int(n_expected)
        #: what the writer process said when it failed (one line), or None
        self.failure: str | None = None

    def spec(self) -> dict[str, Any]:
        """What the writer process needs to open the file (pickled to it)."""
        return {"path": str(self.path), "fs": self.fs, "meta": self.meta,
                "config_text": self.config_text, "chunk_frames": self.chunk_frames,
                "n_expected": self.n_expected}

    def attach(self, hdr, slot: int) -> None:
        """Mirror the range into sink slot ``slot`` of the ring's header ``hdr`` from now on."""
        self._hdr, self._slot = hdr, int(slot)
        self._store()

    def detach(self) -> None:
        self._hdr, self._slot = None, -1

    @property
    def slot(self) -> int:
        return self._slot

    def _store(self) -> None:
        hdr, i = self._hdr, H_SINKS + 2 * self._slot
        if hdr is not None:
            # last first: a writer never sees a begun range with a stale end
            hdr[i + 1] = OPEN_END if self._last is None else self._last
            hdr[i] = -1 if self._first is None else self._first

    @property
    def first_seq(self) -> int | None:
        return self._first

    @first_seq.setter
    def first_seq(self, v: int | None) -> None:
        """Runs in: loop thread (a segment's start) — two stores, no allocation."""
        self._first = v
        if self._hdr is not None:
            self._store()

    @property
    def last_seq(self) -> int | None:
        return self._last

    @last_seq.setter
    def last_seq(self, v: int | None) -> None:
        """Runs in: loop thread (a fault ends a segment) or the caller's — two stores."""
        self._last = v
        if self._hdr is not None:
            self._store()

    def describe_failure(self, exc: BaseException) -> str:
        return self.failure if self.failure is not None else file_failure(self, reason(exc))

    def __repr__(self) -> str:
        return f"FileSink({str(self.path)!r})"


def make_sink(record, n_expected: int, *, fs: float, config, config_text: str,
              last_frame: np.ndarray | None, controller) -> Sink:
    """The sink for ``record`` ("memory", a path or a :class:`RecordSpec`) of a loop.

    The file's metadata: ``kind`` run, the operating point (the last frame's Ω and P_I when
    finite, else the config's ``plant`` section), the controller's source, then ``spec.meta``.
    """
    if isinstance(record, str) and record == "memory":
        return MemorySink(n_expected)
    from rigd.frame import REC

    spec = record if isinstance(record, RecordSpec) else RecordSpec(record)
    plant = config.plant or {}
    meta: dict[str, Any] = {"kind": "run", "omega_rpm": plant.get("omega_rpm", 0.0),
                            "p_inj_bar": plant.get("p_inj_bar", float("nan"))}
    for key in ("omega_rpm", "p_inj_bar"):
        if last_frame is not None and np.isfinite(last_frame[REC[key]]):
            meta[key] = float(last_frame[REC[key]])
    if controller is not None:
        meta["controller"] = str(controller.source)
    meta.update(spec.meta)
    return FileSink(spec.path, fs=fs, meta=meta, config_text=config_text,
                    chunk_frames=config.recorder.chunk_frames, n_expected=n_expected)


