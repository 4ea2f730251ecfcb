"""Compile every big numba kernel once into the on-disk cache before ``make test`` starts.

On a clean clone numba's cache (``$NUMBA_CACHE_DIR/src-<digest>``, :mod:`rigd.jitcache`) is
empty, and each process of the test run — both xdist workers, the timing-sensitive part and
every daemon the tests spawn — used to compile the same kernels at the same time, none of
them finding a cache entry that another was still compiling (CPU minutes per process on a
2-core machine). ``make test`` runs this first: a few processes compile, in parallel, each a
disjoint group of kernels with the argument types the code passes them (through the code
paths that call them: the drivers, :class:`rigd.loop.loop.ControlLoop`, the simulators),
and every later process loads them from the cache. Nothing here is a test: a kernel this
does not reach is still compiled where it is first called, only later.

Run: ``python tests/warm_kernels.py`` (all groups, one process each),
``python tests/warm_kernels.py GROUP ...`` (those groups in this process, one after the other)
or ``python tests/warm_kernels.py --parallel GROUP ...`` (those groups, one process each).
Prints one line per group with its wall time on stderr.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np


def _loop(driver) -> None:
    """Open a lock-step loop on ``driver`` (compiles the cycle, the real-time cycle and the
    lock-step batch with the driver's plant kernel) and run a few cycles."""
    from rigd.loop.loop import ControlLoop
    from rigd.rigconfig import default_config

    centre = driver.describe().get("rest_um")
    sup = {} if centre is None else {"supervisor": {"centre_um": centre}}
    with ControlLoop(default_config(clock={"mode": "lockstep"}, **sup), driver) as loop:
        loop.run_cycles(50)


def _plant(driver) -> None:
    """The driver's open-loop batch and an operating-point change (its parameter block)."""
    from rigd.frame import N_IN

    drives = np.full((20, 4), 5.0)
    driver.run(drives, np.zeros((20, N_IN)))
    driver.set_operating_point(3000.0, 5.0)


def group_sim() -> None:
    """The paper's plant (``rigd_drivers.sim``) and the loop's kernels."""
    from rigd_drivers.sim.driver import SimPlantDriver

    _loop(SimPlantDriver(None, fs=5000.0))
    _plant(SimPlantDriver(None, fs=5000.0))


def group_reynolds() -> None:
    """The physics-grade plant (``rigd_drivers.reynolds``, the default config's) in a loop."""
    from rigd_drivers.reynolds.driver import ReynoldsPlantDriver

    _plant(ReynoldsPlantDriver(None, fs=5000.0))
    _loop(ReynoldsPlantDriver(None, fs=5000.0))


def group_serial() -> None:
    """The front-end's frame protocol, both sides: the emulator and the serial driver over a
    pty (a few hundred frames each way, the emulator's hold and the driver's activation)."""
    from rigd.frame import N_IN
    from rigd_drivers.serial.driver import SerialFrameDriver
    from rigd_drivers.serial.emulator import FrontendEmulator

    with FrontendEmulator(hold_timeout=60.0) as emu:
        drv = SerialFrameDriver({"port": emu.port, "backlog": 256, "timeout_ms": 500,
                                 "first_frame_s": 600.0})
        try:
            drv.activate()
            frame, drive = np.zeros(N_IN), np.full(4, 5.0)
            end = time.monotonic() + 60.0
            while emu.drive_frames < 50 and time.monotonic() < end:
                drv.read(frame)
                drv.write(drive)
                time.sleep(0.0005)
            drv.deactivate(np.full(4, 5.0))
        finally:
            drv.close()


def group_models() -> None:
    """The identification simulators and predictors (linear, cubic RK4 with friction, ZOH
    and FOH), the catalogue effects' compiled operators and the H∞ design's σ̄ kernel, called
    through the functions the code calls them by, on a 2-axis model."""
    from rigd.design.hinf_kernel import weighted_sigma
    from rigd.effects._signals import play
    from rigd.effects.hysteresis import bouc_wen
    from rigd.effects.lure import simulate_lure
    from rigd.effects.restoring_hysteresis import bw_kernel, bw_operator
    from rigd.effects.state_level import simulate_state
    from rigd.ident.feedback import MechanicalFeedback
    from rigd.ident.simulate import predict_mechanical, simulate_mechanical

    fs, n, m = 5000.0, 200, 2
    rng = np.random.default_rng(0)
    K = np.diag([(2 * np.pi * 120.0) ** 2, (2 * np.pi * 150.0) ** 2])
    D, B, x0 = np.diag([40.0, 50.0]), np.eye(m) * 1e4, np.zeros(2 * m)
    u = rng.standard_normal((n, m))
    cubic = MechanicalFeedback(k3=np.full(m, 1e3),
                               friction=np.array([[1.0, 1.0], [1e-3, 1e-3]]))
    for fb, hold in ((None, "zoh"), (None, "foh"), (cubic, "zoh"),
                     (MechanicalFeedback(k3=np.full(m, 1e3)), "foh")):
        y = simulate_mechanical(K, D, B, x0, u, fs, fb, hold)
        predict_mechanical(K, D, B, np.eye(m), x0, u, y, fs, fb, hold)
    A = np.array([[0.0, 1.0], [-1e4, -10.0]])
    simulate_state(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), None, None,
                   np.array([[1.0]]), fs, u[:, :1])
    from rigd.ident.model import LinearPart
    from rigd.ident.simulate import predict_linear, simulate_linear

    for hold in ("zoh", "foh"):  # the Lur'e block of static_nonlinearity's state site
        lp = LinearPart(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), np.zeros((1, 1)),
                        None, (1,), hold)
        simulate_lure(lp, np.zeros(2), np.zeros(1), np.zeros((2, 4)), np.zeros(1),
                      np.zeros(1), 3, u[:, :1], fs)
        # a real-block modal model (rigd.ident.block_kernels): a pair and a real pole
        Am = np.array([[-10.0, 50.0, 0.0], [-50.0, -10.0, 0.0], [0.0, 0.0, -5.0]])
        lm = LinearPart(Am, np.ones((3, 1)), np.ones((1, 3)), np.zeros((1, 1)),
                        np.zeros((3, 1)), (0,), hold)
        ym = simulate_linear(lm, np.zeros(3), u[:, :1], fs)
        predict_linear(lm, np.zeros(3), u[:, :1], ym, fs)
    x = np.ascontiguousarray(u[:, 0])
    play(x, 0.1)
    bouc_wen(x, 0.5)
    bw_operator(x, 0.5, 0.5, 0.5, 1.0)
    a = np.ones(m)
    bw_kernel(K, D, B, a, a, a, a, np.ones(m), np.zeros(m), np.zeros(m), x0, u, 1.0 / fs, 2,
              False)
    nf, nm = 4, 2
    G = np.ones((nm, nf, 2, 2), complex)
    out = np.empty((nm, nf))
    weighted_sigma(np.ones((nf, 2, 2), complex), G, np.ones((nm, nf)), np.ones((nm, nf), complex),
                   np.ones((nm, nf)), np.ones(nf), np.ones(nf), out, np.empty_like(out))


#: one process each, all at once; the loop's kernels are compiled by ``sim`` (``reynolds`` opens
#: its loop after its own plant's long compilation: by then it loads them)
GROUPS = {"sim": group_sim, "reynolds": group_reynolds, "models": group_models,
          "serial": group_serial}


def main(argv: list[str]) -> int:
    names = [a for a in argv if not a.startswith("--")]
    unknown = sorted(set(names) - set(GROUPS))
    if unknown:
        print(f"warm_kernels: no group {', '.join(unknown)} (groups: {', '.join(GROUPS)})",
              file=sys.stderr)
        return 2
    if names and "--parallel" not in argv:
        for name in names:
            t0 = time.perf_counter()
            GROUPS[name]()
            print(f"warm_kernels {name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
        return 0
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, __file__, name]) for name in names or GROUPS]
    rcs = [p.wait() for p in procs]
    print(f"warm_kernels: all groups {time.perf_counter() - t0:.1f} s "
          f"(NUMBA_CACHE_DIR={os.environ.get('NUMBA_CACHE_DIR')})", file=sys.stderr)
    return max(rcs)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
