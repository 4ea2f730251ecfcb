"""Rotor actuator records made without the project's simulator (scipy and numpy only).

Valves as second-order lags (550 Hz, ζ = 0.75) in analog P loops driven by held references r,
with optional piezo creep on their drive: v' = v + Σ_m f_m·L_τm(v), L_τ = 1/(τ s + 1) — the
creep law of docs/plant.md. Discretised exactly for the held drive (``cont2discrete``, ZOH),
sensor noise on the measured positions and drives. The record carries no ``rigd_version``:
data the project did not make.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from rigd.data.record import Record

FS = 5000.0


def binary_prbs(n: int, rng: np.random.Generator, mean_hold: int) -> np.ndarray:
    """Two-level ±1 sequence per axis (n, 2) switching with probability 1/mean_hold per
    sample (geometric holds, mean ``mean_hold`` samples)."""
    sw = rng.random((n, 2)) < 1.0 / mean_hold
    return np.where(np.cumsum(sw, axis=0) % 2 == 0, 1.0, -1.0) * rng.choice([-1.0, 1.0], 2)


def multilevel(n: int, rng: np.random.Generator, levels: int, hold: tuple[int, int]):
    """Random steps over ``levels`` levels in [-1, 1], held ``hold`` samples, per axis."""
    out = np.empty((n, 2))
    for j in range(2):
        k = 0
        while k < n:
            h = int(rng.integers(*hold))
            out[k:k + h, j] = rng.choice(np.linspace(-1, 1, levels))
            k += h
    return out


def actuator_record(r: np.ndarray, fractions=(), taus=(), noise_v: float = 0.003,
                    seed: int = 0, fs: float = FS, kff: float = 1.0, kp: float = 1.5,
                    r0_v: float = 5.0) -> Record:
    """Rotor record of P-closed valve loops driven by held references ``r`` (n, 2), V.

    Per axis a lumped valve, second order (550 Hz, ζ = 0.75), closed by an analog P loop
    v = kff·r + kp·(r − u) (as docs/loop.md without the D part), creep on the drive,
    v' = v + Σ_m f_m·L_τm(v) with the lags settled at the start. The whole loop (valve and
    creep states) is one linear system, discretised exactly for the held r. The record
    carries r_x, r_y, the measured valve positions u_x, u_y and the four valve drives
    v_1..v_4 = r0 ± v (Eq. 1 pairing: x ← v_2, v_4; y ← v_1, v_3), sensor noise
    ``noise_v`` (std, V) on u and on the drives.
    """
    rng = np.random.default_rng(seed + 1000)
    n = r.shape[0]
    wa, za = 2 * np.pi * 550.0, 0.75
    f = np.asarray(fractions, float)
    tau = np.asarray(taus, float)
    m = f.size
    # states [p, ṗ, c_1..c_m]; v = (kff + kp) r − kp p; p̈ = wa²(v + Σ c) − 2 za wa ṗ − wa² p
    A = np.zeros((2 + m, 2 + m))
    B = np.zeros((2 + m, 1))
    A[0, 1] = 1.0
    A[1, 0] = -wa ** 2 * (1.0 + kp)
    A[1, 1] = -2 * za * wa
    A[1, 2:] = wa ** 2
    B[1, 0] = wa ** 2 * (kff + kp)
    for i in range(m):  # ċ_i = (f_i v − c_i)/τ_i
        A[2 + i, 0] = -f[i] * kp / tau[i]
        A[2 + i, 2 + i] = -1.0 / tau[i]
        B[2 + i, 0] = f[i] * (kff + kp) / tau[i]
    C = np.zeros((2, 2 + m))
    C[0, 0] = 1.0                       # u
    C[1, 0] = -kp                       # v = (kff + kp) r − kp u
    D = np.array([[0.0], [kff + kp]])
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, D), 1 / fs, "zoh")
    u = np.empty((n, 2))
    v = np.empty((n, 2))
    for j in range(2):
        _, y, _ = signal.dlsim((Ad, Bd, Cd, Dd, 1 / fs), r[:, j])
        u[:, j], v[:, j] = y[:, 0], y[:, 1]
    u = u + noise_v * rng.standard_normal(u.shape)
    v = v + noise_v * rng.standard_normal(v.shape)
    t = np.arange(n) / fs
    cols = {"t": t, "r_x": r[:, 0], "r_y": r[:, 1], "u_x": u[:, 0], "u_y": u[:, 1],
            "v_1": r0_v + v[:, 1], "v_2": r0_v + v[:, 0], "v_3": r0_v - v[:, 1],
            "v_4": r0_v - v[:, 0]}
    return Record(cols, fs, {"omega_rpm": 0.0, "p_inj_bar": 4.0, "kind": "prbs"},
                  "<foreign rotor>")
