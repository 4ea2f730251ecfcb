"""The experiment process: an experiment's bookkeeping, outside the loop's process.

The daemon (:class:`rigd.service.experiment_host.ExperimentHost`) spawns one process per
experiment, by module name (:func:`rigd.spawn.call` ``("rigd.experiments.process", "main",
...)``): here the spec is validated, the excitation signals are built, the run folder is made,
``manifest.json`` is written after every point and ``.part`` records are renamed
(:func:`rigd.experiments.runner.run_experiment`) — with this process's own interpreter lock,
so none of it holds the 5 kHz cycle's.

What crosses into the loop's process is small and packed, over one pipe
(:class:`LoopProxy`, the ``loop`` the runner drives):

* ``("segment", n, record, events, controller_on, stop_on_fault, pre, post)`` with the
  excitation's ``n`` × 2 float64 samples in shared memory (a sealed memfd passed over the
  pipe); ``record``: ``None``, ``"memory"`` or ``("file", path, meta)``; ``events``:
  ``(offset, ("impact", axis, peak_n, pulse_s))``;
* ``("status",)``, ``("enable", on)``, ``("op", omega_rpm, p_inj_bar)``;

and one-way ``("state", {...})`` progress messages, ending with ``("done", {...})``. The
daemon answers each call with ``("ok", value)`` or ``("raise", kind, text)`` (a failed
recording: ``("raise", "recording", text, n_flushed)``). A connection that ends (the daemon
died) is :class:`~rigd.experiments.points.LoopEnded`: the record being written is kept and
the run ends ``interrupted (process ended)``.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import signal
from types import SimpleNamespace
from typing import Any

from rigd.errors import FaultError, InputError
from rigd.experiments.points import Hit, LoopEnded
from rigd.loop.writer_link import RecordingFailed


class _Hammer:
    """Stands for the loop's simulated plant in this process: its blows become data
    (:class:`~rigd.experiments.points.Hit`) sent with the segment."""

    def impact(self, axis: str, peak_n: float, duration_s: float) -> None:  # pragma: no cover
        raise RuntimeError("a hammer blow is an event of a segment, played by the loop")


class LoopProxy:
    """The ``loop`` of :func:`~rigd.experiments.runner.run_experiment` in the experiment
    process: every call goes to the daemon over ``conn`` (see module docstring).

    Parameters
    ----------
    conn : multiprocessing.connection.Connection
    facts : dict
        What the runner reads of the loop and never changes while it runs: ``fs_hz``,
        ``clock``, ``k_ramp_s``, ``config_path``, ``config_text``, ``source_info``,
        ``hammer`` (the plant has a simulated hammer).
    """

    def __init__(self, conn: Any, facts: dict[str, Any]):
        self.conn = conn
        self.fs = float(facts["fs_hz"])
        self.clock = facts.get("clock", "unknown")
        self.config = SimpleNamespace(loop=SimpleNamespace(k_ramp_s=facts.get("k_ramp_s",
                                                                                0.05)))
        self.loaded = SimpleNamespace(path=facts.get("config_path"),
                                      text=facts.get("config_text"))
        self.source_info = facts.get("source_info")
        self.plant = _Hammer() if facts.get("hammer") else None

    def _call(self, *msg: Any, handle: int | None = None) -> Any:
        from multiprocessing.reduction import send_handle

        try:
            self.conn.send(("call", *msg))
            if handle is not None:
                send_handle(self.conn, handle, None)
            kind, *rest = self.conn.recv()
        except (EOFError, OSError) as exc:        # the daemon is gone
            raise LoopEnded(f"its connection closed during the {msg[0]} call "
                            f"({type(exc).__name__})") from None
        if kind == "ok":
            return rest[0]
        what, text, *more = rest
        if what == "input":
            raise InputError(text)
        if what == "fault":
            raise FaultError(text)
        if what == "recording":
            raise RecordingFailed(text, n_flushed=more[0] if more else None)
        raise RuntimeError(f"the loop's process: {text}")

    def status(self) -> dict[str, Any]:
        return self._call("status")

    def enable_controller(self, on: bool) -> None:
        self._call("enable", bool(on))

    def set_operating_point(self, omega_rpm: float, p_inj_bar: float) -> None:
        self._call("op", float(omega_rpm), float(p_inj_bar))

    def run_segment(self, excitation: Any, *, record: Any = None, events: Any = (),
                    controller_on: bool | None = None, pre: int = 0, post: int = 0,
                    stop_on_fault: bool = False) -> Any:
        """Play ``excitation`` on the daemon's loop (samples through a memfd); its
        :class:`~rigd.loop.segment.SegmentResult`."""
        import numpy as np

        from rigd.loop.segment import SegmentResult
        from rigd.loop.sinks import RecordSpec

        exc = np.ascontiguousarray(excitation, dtype=np.float64)
        if exc.ndim != 2 or exc.shape[1] != 2:
            raise InputError(f"excitation must be an (n, 2) array, got shape {exc.shape}")
        if isinstance(record, RecordSpec):
            record = ("file", str(record.path), dict(record.meta))
        elif record is not None and record != "memory":
            record = ("file", str(record), {})
        evs = []
        for off, fn in events:
            if not isinstance(fn, Hit):
                raise InputError(f"event at {off}: only hammer blows cross to the loop")
            evs.append((int(off), ("impact", fn.axis, float(fn.peak_n), float(fn.pulse_s))))
        fd = samples_fd(exc)
        try:
            res = self._call("segment", len(exc), record, evs, controller_on,
                             bool(stop_on_fault), int(pre), int(post), handle=fd)
        finally:
            os.close(fd)
        return SegmentResult(**res)


def samples_fd(x: Any) -> int:
    """A sealed memfd holding the bytes of the float64 array ``x`` (read by the loop's
    process, which maps it read-only)."""
    import fcntl

    fd = os.memfd_create("rigd-segment", os.MFD_CLOEXEC | os.MFD_ALLOW_SEALING)
    size = max(x.nbytes, 1)
    os.ftruncate(fd, size)
    if x.nbytes:
        with mmap.mmap(fd, size) as mm:
            mm[:x.nbytes] = x.tobytes()
    seals = (getattr(fcntl, "F_SEAL_SHRINK", 2) | getattr(fcntl, "F_SEAL_GROW", 4)
             | getattr(fcntl, "F_SEAL_WRITE", 8) | getattr(fcntl, "F_SEAL_SEAL", 1))
    with contextlib.suppress(OSError):
        fcntl.fcntl(fd, getattr(fcntl, "F_ADD_SEALS", 1033), seals)
    return fd


def unpack(request: dict[str, Any]) -> Any:
    """The :class:`~rigd.experiments.runner.Experiment` of a start request: ``packed`` (what
    the socket process validated: :func:`rigd.service.reader.read_experiment`), ``path`` or
    ``spec`` (read and validated here)."""
    from rigd.experiments.runner import Experiment, load
    from rigd.experiments.schemas import spec_from_dict

    packed = request.get("packed")
    if packed is not None:
        s, p = spec_from_dict(packed["spec"], packed["source"])
        return Experiment(s, p, packed["source"], None, packed.get("spec_sha256"))
    if request.get("spec") is not None:
        return load(request["spec"])
    return load(request["path"])


def main(conn: Any, stop: Any, request: dict[str, Any], run_dir: str | None, runs_root: str,
         facts: dict[str, Any]) -> None:
    """The experiment process: run one experiment on the daemon's loop through ``conn``.

    Parameters
    ----------
    conn : multiprocessing.connection.Connection
    stop : multiprocessing.Event
        Set by the daemon (``experiment.stop``, SAFE, shutdown): stop after the segment.
    request : dict
        ``packed``, ``path`` or ``spec`` (:func:`unpack`).
    run_dir : str or None
        Already confined to the runs folder by the daemon.
    runs_root : str
    facts : dict
        See :class:`LoopProxy`.
    """
    from rigd.experiments.runner import run_experiment
    from rigd.log import get_logger

    # the daemon stops it through ``stop``: a terminal's Ctrl-C goes to the daemon only
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    state: dict[str, Any] = {}

    def update(**kw: Any) -> None:
        state.update(kw)
        conn.send(("state", kw))

    try:
        exp = unpack(request)
        update(name=exp.name, kind=exp.spec.kind)
        man = run_experiment(
            exp, LoopProxy(conn, facts), run_dir,
            lambda done, total, text: update(done=done, total=total, last=text),
            runs_root=runs_root, stop=stop, log=get_logger("rigd.experiment"),
            on_start=lambda m: update(state="running", run_dir=str(m.run_dir),
                                      manifest=str(m.path)))
        final = {"state": man.status, "message": man.message, "missing": man.missing,
                 "fault": man.fault}
    except InputError as exc:
        final = {"state": "failed", "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 - reported through status
        final = {"state": "failed", "message": f"internal error: {exc!r}"}
    with contextlib.suppress(OSError, EOFError, BrokenPipeError):
        conn.send(("done", final))
    conn.close()
