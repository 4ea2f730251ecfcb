"""A large valid controller file (order 64, full precision, continuous form and weights: the
~0.7 MB YAML that stalled the loop when it was parsed in the loop's process)."""

import numpy as np

from rigd.controller import save_controller


def write_big_controller(path, *, order: int = 64, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((order, order))
    A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))          # stable: spectral radius 0.9
    B = rng.standard_normal((order, 2)) * 1e-3
    C = rng.standard_normal((2, order)) * 1e-3
    D = np.zeros((2, 2))
    cont = {k: m.tolist() for k, m in zip("ABCD", (A, B, C, D))}
    save_controller(path, A, B, C, D, fs_hz=5000.0, continuous=cont,
                    weights={"samples": rng.standard_normal(24_000).tolist()})
