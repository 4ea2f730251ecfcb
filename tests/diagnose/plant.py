"""A small simulated rig for the diagnosis tests: a 2-axis bearing (Eq. 4) or a lumped valve
pair (Eq. 8) simulated by rigd.ident's mechanical simulator, with any catalogue effect switched
on in the simulation (a state feedback, a shifted input, a parallel mode; the base model of
the test is unaware of it).

How each effect is posed (docs/diagnose.md):

* ``runout``: 1× and 2× shaft-angle harmonics added to e_x, e_y at Ω = 3000 rpm;
* ``delay``: the valve positions act 4 samples (0.8 ms) late;
* ``actuator_dynamics``: the plant is driven by valve positions u = H_a(s) r (corner
  ~250 Hz), the model is fed with the references r;
* ``hysteresis`` / ``creep``: valve (actuator) sub-model r -> u whose input passes through
  play operators / slow lags first;
* ``cubic_stiffness``: k3 p³ on both axes (≈ 35 % of the linear force at the largest p);
* ``extra_mode``: a lightly damped mode at 430 Hz in parallel;
* ``cross_coupling``: gyroscopic cross damping ±Ω g at Ω > 0 with a decoupled base model.
"""

from __future__ import annotations

import numpy as np

from rigd.effects._signals import lag1, play
from rigd.ident.feedback import MechanicalFeedback
from rigd.ident.iddata import IdData
from rigd.ident.simulate import ExtraMode, parallel_modes, simulate_mechanical

FS = 5000.0
# operating points: natural frequencies (Hz) and damping ratio of the two axes
POINTS = {"low": (110.0, 135.0, 0.08), "mid": (140.0, 170.0, 0.06), "high": (180.0, 215.0, 0.05)}


def excitation(n: int, rng: np.random.Generator, levels: int = 7, hold=(4, 25)) -> np.ndarray:
    """Multi-level random steps, held ``hold`` samples, independent per axis, in [-1, 1]."""
    out = np.empty((n, 2))
    for j in range(2):
        k = 0
        while k < n:
            h = int(rng.integers(*hold))
            out[k:k + h, j] = rng.integers(0, levels) / (levels - 1) * 2 - 1
            k += h
    return out


def bearing(effects=(), seed: int = 0, point: str = "mid", seconds: float = 1.6,
            noise: float = 0.01) -> IdData:
    """Bearing sub-model data u -> e (µm) with hidden ``effects``."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    f1, f2, z = POINTS[point]
    w = 2 * np.pi * np.array([f1, f2])
    K = np.diag(w ** 2) + np.array([[0, 0.08], [0.05, 0]]) * w[0] ** 2
    D = np.diag(2 * z * w)
    B = np.diag(w ** 2 * 2.0) + np.array([[0, 0.1], [-0.1, 0]]) * w[0] ** 2
    r = excitation(n, rng, hold=(2, 12))
    u = r.copy()
    fb: dict = {}
    modes: list[ExtraMode] = []
    omega_rpm = 0.0
    if "actuator_dynamics" in effects:
        tau = 1 / (2 * np.pi * 250)
        u = np.column_stack([lag1(lag1(r[:, j], tau, FS), 0.5 * tau, FS) for j in range(2)])
    uu = u
    if "delay" in effects:   # 4 samples, zero before the start
        uu = np.zeros_like(u)
        uu[4:] = u[:-4]
    if "extra_mode" in effects:
        modes = [ExtraMode(2 * np.pi * 430, 0.015, np.array([1.0, 0.6]) * 1.5e5,
                           np.array([1.0, 0.7]) * 12.0)]
    if "cross_coupling" in effects:
        omega_rpm = 3000.0
        g = 0.9 * 2 * z * w[0]
        fb["dD"] = np.array([[0.0, g], [-g, 0.0]])
    if "runout" in effects:
        omega_rpm = 3000.0
    if "cubic_stiffness" in effects:
        p = simulate_mechanical(K, D, B, np.zeros(4), u, FS)   # scale on the undelayed input
        pmax = np.percentile(np.abs(p), 99, axis=0)
        fb["k3"] = 0.35 * np.diag(K) / pmax ** 2
    e = simulate_mechanical(K, D, B, np.zeros(4), uu, FS, MechanicalFeedback(**fb))
    add = parallel_modes(modes, uu, 1.0 / FS, "zoh")
    e = e if add is None else e + add
    t = np.arange(n) / FS
    phi = np.mod(2 * np.pi * omega_rpm / 60 * t, 2 * np.pi)
    if "runout" in effects:
        s = e.std(axis=0)
        e = e + np.column_stack([0.3 * s[0] * np.cos(phi + 0.4) + 0.1 * s[0] * np.sin(2 * phi),
                                 0.25 * s[1] * np.sin(phi + 0.4)])
    e = e + noise * e.std(axis=0) * rng.standard_normal(e.shape)
    aux = {"phi": phi} if omega_rpm > 0 else {}
    return IdData(r if "actuator_dynamics" in effects else u, e, FS, ["u_x", "u_y"],
                  ["e_x", "e_y"], aux, {"omega_rpm": omega_rpm, "submodel": "bearing"})


def actuator(effects=(), seed: int = 0, seconds: float = 1.6, noise: float = 0.01) -> IdData:
    """Actuator sub-model data r -> u (V) with hidden ``effects`` (hysteresis, creep)."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    r = excitation(n, rng, hold=(20, 400))
    v = r.copy()
    if "hysteresis" in effects:
        v = np.column_stack([0.6 * r[:, j] + 0.4 * play(np.ascontiguousarray(r[:, j]), 0.5)
                             for j in range(2)])
    if "creep" in effects:
        v = np.column_stack([v[:, j] + 0.25 * (lag1(v[:, j], 0.04, FS) - v[:, j])
                             for j in range(2)])
    p = 2 * np.pi * np.array([300.0, 900.0])
    K = np.diag([p[0] * p[1]] * 2)
    D = np.diag([p[0] + p[1]] * 2)
    u = simulate_mechanical(K, D, 0.95 * K, np.zeros(4), v, FS)
    u = u + noise * u.std(axis=0) * rng.standard_normal(u.shape)
    return IdData(r, u, FS, ["r_x", "r_y"], ["u_x", "u_y"], {}, {"submodel": "actuator"})
