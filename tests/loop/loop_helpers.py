"""Helpers for the loop tests: a fault-injecting wrapper around the simulated plant, factories."""

from __future__ import annotations

import numpy as np

from rigd.driver import FastDriver


class InjectingDriver(FastDriver):
    """The simulated plant without its compiled kernel (per-cycle read/write path), with a
    hook that may corrupt the frame after a given cycle: ``inject(frame, cycle)``."""

    name = "inject"

    def __init__(self, plant, inject=None, fail_at=None):
        super().__init__({}, fs=plant.fs)
        self.plant = plant
        self.inject = inject
        self.fail_at = fail_at
        self.n = 0

    def read(self, frame_in):
        self.plant.read(frame_in)
        if self.fail_at is not None and self.n == self.fail_at:
            raise OSError("device unplugged")
        if self.inject is not None:
            self.inject(frame_in, self.n)

    def write(self, drive):
        self.plant.write(drive)
        self.n += 1

    def set_operating_point(self, omega, p):
        self.plant.set_operating_point(omega, p)


def make_plant(fs=5000.0, **opts):
    from rigd_drivers.sim.driver import SimPlantDriver

    return SimPlantDriver({"seed": 5, **opts}, fs=fs)


def random_stable_controller(n=4, seed=0, fs=5000.0):
    """A random stable discrete 2x2 state space (spectral radius <= 0.95)."""
    from rigd.controller import Controller

    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.95 / max(abs(np.linalg.eigvals(A)))
    B = rng.normal(size=(n, 2))
    C = rng.normal(size=(2, n))
    D = rng.normal(size=(2, 2))
    return Controller(A, B, C, D, fs)
