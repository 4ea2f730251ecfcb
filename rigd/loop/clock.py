"""Clocks: real-time set-up (SCHED_FIFO, mlockall, CPU pinning, gc) and the deadline wait.

The real-time loop thread sleeps until ``spin_us`` before each deadline, then busy-waits to the
deadline (never a whole period: under SCHED_FIFO the kernel's RT throttling would stall it).
The lock-step (virtual) clock needs none of this: it runs compiled batches back to back.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import os
import sys
import time

MCL_CURRENT, MCL_FUTURE = 1, 2


def try_realtime(priority: int, cpu: int | None) -> list[str]:
    """Make the *calling thread* real-time where permitted; return the problems (for ONE warning).

    SCHED_FIFO at ``priority`` (Linux applies it to the calling thread), ``mlockall`` of the
    process memory, and optionally pin the thread to ``cpu``.
    """
    problems: list[str] = []
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as exc:
        problems.append(f"SCHED_FIFO priority {priority} not permitted ({exc.__class__.__name__}: "
                        f"{getattr(exc, 'strerror', exc)})")
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
            err = ctypes.get_errno()
            problems.append(f"mlockall failed ({os.strerror(err)})")
    except OSError as exc:
        problems.append(f"mlockall unavailable ({exc})")
    if cpu is not None:
        try:
            os.sched_setaffinity(0, {cpu})
        except (OSError, ValueError) as exc:
            problems.append(f"cannot pin to CPU {cpu} ({exc})")
    return problems


def boost_threads(native_ids, priority: int) -> None:
    """Give other threads of this process SCHED_FIFO ``priority`` (best effort, silent)."""
    for tid in native_ids:
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
        except (OSError, AttributeError):
            pass


@contextlib.contextmanager
def boosted(priority: int | None):
    """Run the block at SCHED_FIFO ``priority`` in the *calling thread*, then restore its
    policy (best effort; None: unchanged).

    For short preparations in another thread while the real-time loop runs (an operating
    point's parameter block): holding the GIL, an ordinary thread preempted by another process
    stalls the loop thread until it runs again (priority inversion); boosted just below the
    loop it is not preempted by ordinary processes.
    """
    if priority is None:
        yield
        return
    try:
        old_policy, old_param = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError):
        yield
        return
    try:
        yield
    finally:
        try:
            os.sched_setscheduler(0, old_policy, old_param)
        except OSError:
            pass


def drop_realtime() -> None:
    """Return the calling thread to SCHED_OTHER (after the loop ends)."""
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError):
        pass


def freeze_gc() -> None:
    """Collect once, move every object to the permanent generation, disable the collector."""
    gc.collect()
    gc.freeze()
    gc.disable()


def thaw_gc() -> None:
    gc.unfreeze()
    gc.enable()


def fast_switch_interval(seconds: float = 2e-4) -> float:
    """Shorten the GIL switch interval so the loop thread regains the GIL quickly; returns old."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(seconds)
    return old


_perf_ns = time.perf_counter_ns
_sleep = time.sleep


def wait_until(deadline_ns: int, spin_ns: int) -> int:
    """Sleep until ``spin_ns`` before ``deadline_ns`` (perf_counter_ns), then spin; return wake
    time."""
    rem = deadline_ns - _perf_ns()
    if rem > spin_ns:
        _sleep((rem - spin_ns) * 1e-9)
    now = _perf_ns()
    while now < deadline_ns:
        now = _perf_ns()
    return now
