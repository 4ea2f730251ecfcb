"""Fault-injection helpers: a fault injected at the driver boundary of the real loop, and the
checks every fault must pass in the recording (safe state within one cycle, latched code,
no frame lost before the fault)."""

import contextlib
import time

import numpy as np
from daemon_helpers import make_config

from rigd.controller import save_controller
from rigd.driver import FastDriver
from rigd.frame import REC
from rigd.loop.app import build_drivers
from rigd.loop.clock import boosted
from rigd.loop.loop import ControlLoop
from rigd.recording.h5sink import open_recording
from rigd.rigconfig import load_config

R0 = 5.0


class Injector(FastDriver):
    """The real simulated plant behind a driver boundary where a fault can be switched on.

    It deliberately hides the plant's compiled kernel, so the loop calls ``read``/``write``
    every cycle exactly as it does for a hardware driver. ``fault(frame_in)`` mutates the
    delivered frame (or raises, or sleeps) once :attr:`armed` is set.
    """

    name = "injector"

    def __init__(self, inner, fault):
        super().__init__({}, fs=inner.fs)
        self.inner = inner
        self.fault = fault
        self.armed = False

    def open(self):
        self.inner.open()

    def close(self):
        self.inner.close()

    def read(self, frame_in):
        self.inner.read(frame_in)
        if self.armed:
            self.fault(frame_in)

    def write(self, drive):
        self.inner.write(drive)

    def counters(self):
        return self.inner.counters()

    def set_operating_point(self, omega_rpm, p_inj_bar):
        self.inner.set_operating_point(omega_rpm, p_inj_bar)


@contextlib.contextmanager
def loop_caller(config):
    """Run the calling thread (the test's, which drives the loop's API) at SCHED_FIFO just
    below the real-time loop thread, as the daemon runs its service threads
    (``rigd.service.daemon.Daemon._helper_priority``); back to SCHED_OTHER afterwards. Best
    effort: without the permission nothing changes.

    Why (issue 16 item 6): the loop thread (SCHED_FIFO) needs the interpreter lock each
    cycle. The test's thread, an ordinary one, took it for its own work (opening the HDF5
    recording, waiting, polling) and was then preempted by the loaded machine while holding
    it: the loop waited for it — a priority inversion the daemon does not have. It made
    cycles late by the dozen at the start of a segment (``overrun_storm`` latched at seq
    ~800, before the injection) and could hold the loop longer than the front-end's host
    timeout (``driver_status``)."""
    with boosted(max(1, int(config.clock.priority) - 1)):
        yield


def controller_file(tmp_path):
    path = tmp_path / "k.yaml"
    save_controller(path, [[0.99]], [[0.001, 0.0005]], [[1.0], [0.5]], [[0.0, 0.0], [0.0, 0.0]],
                    fs_hz=5000.0)
    return path


def excitation(n, amp=0.3, seed=0):
    """A two-level random sequence, V (r_p != r0 before the fault, so the change shows)."""
    rng = np.random.default_rng(seed)
    return amp * np.sign(rng.standard_normal((n, 2)))


def lockstep_fault(tmp_path, fault, *, at=1500, n=4000, plant=None, supervisor=None,
                   clock="lockstep", clock_opts=None):
    """Run the real loop with K∞ on and an excitation playing, arm ``fault`` at cycle ``at``
    of the segment, record the segment to HDF5. Returns (frames, faults, first_seq)."""
    sections = {"clock": {"spin_us": 0.0, **(clock_opts or {})}}
    if plant:
        sections["plant"] = plant
    if supervisor:
        sections["supervisor"] = supervisor
    lc = load_config(make_config(tmp_path, **sections))
    fast, slow, hz = build_drivers(lc)
    inj = Injector(fast, fault)
    loop = ControlLoop(lc, inj, slow_drivers=slow, slow_poll_hz=hz,
                       controller=controller_file(tmp_path), clock=clock)
    rec = tmp_path / "fault.h5"
    caller = loop_caller(lc.config) if clock == "realtime" else contextlib.nullcontext()
    with caller, loop:
        loop.enable_controller(True)
        loop.run_cycles(600)  # K∞ blended in (k_ramp_s = 0.05 s = 250 cycles)
        res = loop.run_segment(excitation(n), record=str(rec),
                               events=[(at, lambda: setattr(inj, "armed", True))])
        faults = loop.faults()
    return read_frames(rec), faults, res


def read_frames(path):
    """All recorded frames; SWMR-aware (a recording cut short by a crash or a full disk keeps
    the file's write flag set, which a plain ``h5py.File(path, "r")`` refuses)."""
    with open_recording(path) as f:
        return f["frames"][:]


def assert_safe_after_fault(fr, code, *, armed_at=None, max_latency=None, faults=None):
    """The checks of the fault-injection suite on recorded frames ``fr``.

    * every frame there, in order (seq contiguous): nothing before the fault was lost;
    * no fault before it was injected; the fault is ``code`` and stays latched;
    * from the cycle after the one that latched it (within one cycle): references at r0
      (r_p,i = r0, r = 0), K∞ off, excitation off;
    * before it: K∞ on and the excitation playing (so the change is real).
    ``faults`` (the loop's fault log, optional) is shown when a check fails, so a fault
    latched early names its cause (status bits, text).
    Returns the index of the first faulted frame.
    """
    seq = fr[:, REC["seq"]]
    assert np.all(np.diff(seq) == 1), "recorded frames are contiguous"
    fault = fr[:, REC["fault"]]
    hit = np.flatnonzero(fault != 0)
    assert hit.size, f"a fault was latched; fault log {faults}"
    i = int(hit[0])
    assert fault[i] == code, f"latched {fault[i]:g}, expected {code}; fault log {faults}"
    assert np.all(fault[i:] == code), "the fault stays latched"
    if armed_at is not None:
        assert i >= armed_at, f"no fault before the injection (at {i}); fault log {faults}"
        if max_latency is not None:
            assert i - armed_at <= max_latency, f"detected {i - armed_at} cycles after injection"
    pre = fr[:i]
    assert np.any(pre[:, REC["k_on"]] == 1) and np.any(pre[:, REC["x_x"]] != 0)
    assert np.any(np.abs(pre[:, REC["r_p1"]] - R0) > 0.1)
    safe = fr[i + 1:]
    assert len(safe) > 0
    for k in range(1, 5):
        np.testing.assert_allclose(safe[:, REC[f"r_p{k}"]], R0, err_msg=f"r_p{k} at r0")
    assert np.all(safe[:, REC["r_x"]] == 0) and np.all(safe[:, REC["r_y"]] == 0)
    assert np.all(safe[:, REC["k_on"]] == 0), "K∞ off"
    assert np.all(safe[:, REC["x_x"]] == 0) and np.all(safe[:, REC["x_y"]] == 0), "excitation off"
    return i


def wait_for(pred, timeout=10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return False
