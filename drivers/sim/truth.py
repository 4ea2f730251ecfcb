"""The simulated plant's true G_p(Ω, P_I), for tests and for ``rigd demo --quick`` (no
identified operating-range model there). It lives with the simulator it reads (``rigd.design``
must not import the simulator).

G_p = G_bear·G_act with G_bear from ``rigd_drivers.plant.physics.bearing_ss`` (Eqs. 5–6) and
G_act the lumped valve pairs under their PD loops (``lumped_actuator_tf``, Eq. 8), both as the
simulated plant implements them. Discrete at ``fs_hz`` (ZOH bearing) — this is the loop the
lock-step simulation runs — or, for design, continuous with a second-order actuator fitted to
the discrete actuator's frequency response.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np


def _sp():
    from rigd_drivers.plant import physics as sim_physics

    return sim_physics


def actuator_fit(fs_hz: float = 5000.0):
    """((κ, p1, p2) for x, y): the continuous second-order fit (Eq. 8) of the valves."""
    return _act_fit(fs_hz)


@lru_cache(maxsize=4)
def actuator_z(fs_hz: float = 5000.0):
    """Discrete 2×2 diagonal r → u of the simulated valves (PD loops included)."""
    import control

    sp = _sp()
    hx = control.ss(sp.lumped_actuator_tf("x", fs=fs_hz))
    hy = control.ss(sp.lumped_actuator_tf("y", fs=fs_hz))
    return control.append(hx, hy)


def plant_z(omega_rpm: float, p_inj_bar: float, fs_hz: float = 5000.0, force_inputs=False):
    """True discrete G_p(z): r (V) → p (µm); with ``force_inputs`` also f (N) → p."""
    import control

    sp = _sp()
    Gb = control.c2d(control.ss(sp.bearing_ss(omega_rpm, p_inj_bar, force_inputs=force_inputs)),
                     1.0 / fs_hz, "zoh")
    A = actuator_z(fs_hz)
    if not force_inputs:
        return Gb * A
    I2 = control.ss([], [], [], np.eye(2), 1.0 / fs_hz)
    return Gb * control.append(A, I2)


@lru_cache(maxsize=4)
def _act_fit(fs_hz: float):
    from scipy.optimize import least_squares

    sp = _sp()
    T = 1.0 / fs_hz
    ff = np.linspace(5.0, 1000.0, 200)
    out = []
    for ax in ("x", "y"):
        h = sp.lumped_actuator_tf(ax, fs=fs_hz)(np.exp(2j * np.pi * ff * T))

        def res(th, h=h):
            s = 2j * np.pi * ff
            m = th[0] / ((s / th[1] + 1) * (s / th[2] + 1)) * np.exp(-s * T / 2)
            r = (m - h) / np.abs(h)
            return np.r_[r.real, r.imag]

        out.append(least_squares(res, [1.2, 2 * np.pi * 400, 2 * np.pi * 1500]).x)
    return tuple(tuple(float(v) for v in th) for th in out)


def actuator_s(fs_hz: float = 5000.0):
    """Continuous second-order (Eq. 8) fit of the simulated actuator (2×2 diagonal)."""
    import control

    hs = []
    for k, p1, p2 in _act_fit(fs_hz):
        hs.append(control.ss(control.tf([k * p1 * p2], [1.0, p1 + p2, p1 * p2])))
    return control.append(*hs)


def plant_s(omega_rpm: float, p_inj_bar: float, fs_hz: float = 5000.0):
    """Continuous G_p(s) = G_bear(s)·G_act(s) of the simulated plant (design model)."""
    import control

    return control.ss(_sp().bearing_ss(omega_rpm, p_inj_bar)) * actuator_s(fs_hz)
