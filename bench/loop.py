"""Loop benchmark: lock-step throughput, per-cycle compute time, real-time lateness.

Figures (``make bench`` / ``python -m bench loop``; ``RIGD_BENCH_LOOP=op_change,compute`` runs
only those parts: ``lockstep``, ``compute``, ``realtime``, ``op_change``):

* ``lockstep_cycles_per_s``: loop + simulated plant + recording of every frame to an HDF5 file,
  10^6 cycles, wall time until the file is closed.
* ``loop_compute_us`` {p50, p99, p999}: one real-time cycle call (``kernels.rt_cycle``: Eq. 1, a
  4th-order K∞, four PD loops, supervisor, frame into the ring) timed from Python around each
  call, dispatch included, plant excluded; the ring populated first, as the real-time loop's
  ``mlockall`` does (docs/loop.md). ``loop_compute_us_k14``: the same with the 14-state
  K∞ that ``make demo`` deploys (docs/design.md: order 4 does not stabilise).
* ``loop_kernel_ns`` (``loop_kernel_ns_k14``): the same cycle's cost inside a compiled batch (no
  dispatch), mean.
* ``rt_lateness_us`` {p50, p99, p999, max}, ``rt_compute_us`` and ``rt_miss_fraction``: 10 s at
  5 kHz on the real-time clock with the simulated plant (``ControlLoop.timing()``).
* ``op_change_miss_fraction``: miss fraction (overruns / cycles) on the real-time clock while
  the operating point changes every 100 ms, and ``op_change_idle_miss_fraction`` in the same
  run without changes (alternating 1 s blocks, 10 s in all; target: changes <= idle + 1e-3).
"""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np
from numba import njit

RT_SECONDS = float(os.environ.get("RIGD_BENCH_RT_S", "10"))


def _controller(n=4, seed=0):
    """A stable random discrete K∞ with n states (4: the issue's figure; 14: what `make demo`
    deploys)."""
    from rigd.controller import Controller

    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.9 / max(abs(np.linalg.eigvals(A)))
    return Controller(A, 0.01 * rng.normal(size=(n, 2)), 0.01 * rng.normal(size=(2, n)),
                      np.zeros((2, 2)), 5000.0)


def _plant():
    from rigd_drivers.sim.driver import SimPlantDriver

    return SimPlantDriver({"seed": 1}, fs=5000.0)


def lockstep_throughput(n: int = 1_000_000) -> float:
    from rigd.loop.loop import ControlLoop
    from rigd.loop.sinks import RecordSpec
    from rigd.rigconfig import default_config

    cfg = default_config(clock={"mode": "lockstep", "batch_cycles": 16384})
    loop = ControlLoop(cfg, _plant(), controller=_controller())
    with tempfile.TemporaryDirectory() as tmp, loop:
        loop.enable_controller(True)
        loop.run_cycles(20000)                       # warm-up (compiled, caches hot)
        # the HDF5 writer process is spawned on the first recording: not in the timed part
        loop.run_segment(np.zeros((1000, 2)), record=RecordSpec(os.path.join(tmp, "w.h5")))
        exc = np.zeros((n, 2))
        t0 = time.perf_counter()
        res = loop.run_segment(exc, record=RecordSpec(os.path.join(tmp, "b.h5")))
        wall = time.perf_counter() - t0
    assert res.n_frames == n
    return n / wall


@njit(cache=True, nogil=True)
def _null_plant(state, params, drive, frame_in):
    frame_in[11] += 1.0           # advance drv_seq like a healthy driver, nothing else


def compute_samples(n: int = 200_000, order: int = 4):
    """Per-call times (ns) of ``rt_cycle`` from Python with an ``order``-state K∞, and the
    in-batch mean (ns)."""
    from rigd.loop import cycle as K
    from rigd.loop import layout as L
    from rigd.loop.loop import ControlLoop
    from rigd.rigconfig import default_config

    plant = _plant()
    cfg = default_config(clock={"mode": "lockstep"}, recorder={"ring_frames": 1 << 18})
    loop = ControlLoop(cfg, plant, controller=_controller(order))
    # the real-time loop thread runs with its memory locked and populated (mlockall): the
    # shared-memory ring's first-touch page faults (one per ~16 frames) are not part of a cycle
    loop.recorder.shared.populate()
    s = loop.state
    s.st[L.S_K_TARGET] = 1.0
    fin = np.zeros(13)
    plant.read(fin)
    prm, st, drive, ring, hist = s.prm, s.st, s.drive, loop.recorder.ring, s.hist
    exc = np.zeros((1, 2))
    sw = loop.safe.word
    perf = time.perf_counter_ns
    out = np.empty(n, dtype=np.int64)
    rt = K.rt_cycle
    for _ in range(2000):
        fin[11] += 1.0
        rt(fin, prm, st, drive, ring, exc, -1, hist, 0, -1, sw)
    block = 1 << 16
    for b0 in range(0, n, block):
        st[L.S_RD] = st[L.S_W]                 # the writer's job, outside the timed calls
        for i in range(b0, min(n, b0 + block)):
            fin[11] += 1.0
            t0 = perf()
            rt(fin, prm, st, drive, ring, exc, -1, hist, 0, -1, sw)
            out[i] = perf() - t0
    assert st[L.S_FAULT] == 0, st[L.S_FAULT]
    # in-batch: the same cycle without dispatch, with a no-op plant
    m = 100_000
    st[L.S_RD] = st[L.S_W]
    z = np.zeros(1)
    K.lockstep_batch(_null_plant, z, z, fin, prm, st, drive, ring, exc, -1, 1000, sw)
    kernel_ns = float("inf")
    for _ in range(5):            # best of 5: the machine is shared
        st[L.S_RD] = st[L.S_W]
        t0 = perf()
        K.lockstep_batch(_null_plant, z, z, fin, prm, st, drive, ring, exc, -1, m, sw)
        kernel_ns = min(kernel_ns, (perf() - t0) / m)
    loop.close()
    return out, kernel_ns


def realtime(seconds: float = RT_SECONDS) -> dict:
    from rigd.loop.loop import ControlLoop
    from rigd.rigconfig import default_config

    cfg = default_config(clock={"mode": "realtime"})
    loop = ControlLoop(cfg, _plant(), controller=_controller())
    with loop:
        loop.enable_controller(True)
        loop.start()
        loop.wait(seconds)
        loop.stop()
    t = loop.timing()
    t["rt_warnings"] = loop.rt_warnings
    return t


def op_change(seconds: float = RT_SECONDS, every_s: float = 0.1) -> dict:
    """Miss fraction with an operating-point change every ``every_s`` vs idle, same run.

    One real-time run alternates 1 s blocks: idle, then changes every 100 ms (from this
    thread, as the service would), so both see the same machine load. Returns both fractions.
    """
    from rigd.loop.loop import ControlLoop
    from rigd.rigconfig import default_config

    cfg = default_config(clock={"mode": "realtime"},
                         supervisor={"overrun_storm_count": 10**9})
    loop = ControlLoop(cfg, _plant(), controller=_controller())
    rng = np.random.default_rng(0)
    acc = {"idle": [0, 0], "change": [0, 0]}          # overruns, cycles
    n_changes = 0
    with loop:
        loop.enable_controller(True)
        loop.start()
        loop.wait(0.5)                                 # past the start-up
        for b in range(max(2, int(round(seconds)))):
            mode = "idle" if b % 2 == 0 else "change"
            t = loop.timing()
            o0, c0 = t["overruns"], t["cycles"]
            t_end = time.monotonic() + 1.0
            while time.monotonic() < t_end:
                if mode == "change":
                    loop.set_operating_point(float(rng.uniform(0, 6000)),
                                             float(rng.uniform(3, 7)))
                    n_changes += 1
                loop.wait(min(every_s, max(0.0, t_end - time.monotonic())))
            t = loop.timing()
            acc[mode][0] += t["overruns"] - o0
            acc[mode][1] += t["cycles"] - c0
        loop.stop()
    frac = {k: (o / c if c else float("nan")) for k, (o, c) in acc.items()}
    return {"op_change_miss_fraction": frac["change"],
            "op_change_idle_miss_fraction": frac["idle"],
            "op_change_count": n_changes}


def _percentiles(us: np.ndarray) -> dict:
    return {"p50": round(float(np.percentile(us, 50)), 3),
            "p99": round(float(np.percentile(us, 99)), 3),
            "p999": round(float(np.percentile(us, 99.9)), 3),
            "max": round(float(us.max()), 3)}


#: the parts of the section; ``RIGD_BENCH_LOOP=op_change,compute`` runs only those (A/B runs)
PARTS = ("lockstep", "compute", "realtime", "op_change")


def _parts() -> tuple[str, ...]:
    want = [p.strip() for p in os.environ.get("RIGD_BENCH_LOOP", "").split(",") if p.strip()]
    bad = [p for p in want if p not in PARTS]
    if bad:
        raise SystemExit(f"RIGD_BENCH_LOOP: unknown part(s) {', '.join(bad)} "
                         f"(parts: {', '.join(PARTS)})")
    return tuple(want) or PARTS


def run() -> dict:
    parts = _parts()
    out: dict = {}
    if "lockstep" in parts:
        out["lockstep_cycles_per_s"] = round(lockstep_throughput())
    if "compute" in parts:
        samples, kernel_ns = compute_samples()
        samples14, kernel14_ns = compute_samples(order=14)
        out.update({
            "loop_compute_us": _percentiles(samples / 1000.0),
            "loop_kernel_ns": round(kernel_ns, 1),
            "loop_compute_us_k14": _percentiles(samples14 / 1000.0),
            "loop_kernel_ns_k14": round(kernel14_ns, 1),
        })
    if "realtime" in parts:
        t = realtime()
        out.update({
            "rt_lateness_us": t["lateness_us"],
            "rt_compute_us": t["compute_us"],
            "rt_miss_fraction": t["overrun_fraction"],      # overruns / cycles
            "rt_periods_missed_fraction": t["miss_fraction"],  # + skipped periods
            "rt_cycles": t["cycles"],
            "rt_overruns": t["overruns"],
            "rt_skipped_periods": t["skipped_periods"],
            "rt_seconds": RT_SECONDS,
            "rt_sched_fifo": not any("SCHED_FIFO" in w for w in t["rt_warnings"]),
        })
    if "op_change" in parts:
        out.update(op_change())
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
