"""Simulated rotor records with known parameters for the identification tests.

PRBS references (held 1..4 samples) drive the actuator model (Eqs. 8-10); its output u drives
the bearing model (Eqs. 5-7); both are simulated exactly (ZOH at fs) and measured with white
noise. Optionally a synchronous run-out term locked to the shaft angle is added to e.
"""

import numpy as np

from rigd.data.record import Record
from rigd.ident.simulate import simulate_mechanical

FS = 5000.0
W1, W2 = 2 * np.pi * 110.0, 2 * np.pi * 160.0
K_TRUE = np.array([[W1 ** 2, 0.1 * W1 * W2], [-0.05 * W1 * W2, W2 ** 2]])
D_TRUE = np.array([[2 * 0.05 * W1, 5.0], [-3.0, 2 * 0.04 * W2]])
B_TRUE = K_TRUE @ np.array([[5.0, 0.5], [-0.3, 4.0]])
# actuator: poles (rad/s) and gains per axis
ACT_POLES = {"x": (2 * np.pi * 150.0, 2 * np.pi * 600.0),
             "y": (2 * np.pi * 180.0, 2 * np.pi * 700.0)}
ACT_GAIN = {"x": 1.9, "y": 2.1}


def actuator_matrices():
    K = np.diag([ACT_POLES[a][0] * ACT_POLES[a][1] for a in "xy"])
    D = np.diag([ACT_POLES[a][0] + ACT_POLES[a][1] for a in "xy"])
    B = np.diag([ACT_GAIN[a] * K[i, i] for i, a in enumerate("xy")])
    return K, D, B


def prbs(n, rng, nu=2, hold=(1, 4)):
    out = np.empty((n, nu))
    for j in range(nu):
        k = 0
        while k < n:
            h = rng.integers(hold[0], hold[1] + 1)
            out[k:k + h, j] = rng.choice([-1.0, 1.0])
            k += h
    return out


def rotor_record(n=15000, seed=0, noise=0.02, omega_rpm=0.0, p_inj_bar=4.0, runout=0.0,
                 kind="prbs", excite=True, kscale=1.0):
    """A simulated rotor record; ``noise`` is relative to each channel's std."""
    rng = np.random.default_rng(seed)
    r = prbs(n, rng) if excite else np.zeros((n, 2))
    Ka, Da, Ba = actuator_matrices()
    u = simulate_mechanical(Ka, Da, Ba, np.zeros(4), r, FS)
    # u is a measured, continuous signal: linear between samples (FOH), as in the sim plant
    e = simulate_mechanical(K_TRUE * kscale, D_TRUE, B_TRUE, np.zeros(4), u, FS,
                            hold="foh")
    sd_u = 0.5 if not excite else u.std(0)
    sd_e = 5.0 if not excite else e.std(0)
    u = u + noise * sd_u * rng.standard_normal(u.shape)
    e = e + noise * sd_e * rng.standard_normal(e.shape)
    t = np.arange(n) / FS
    phi = np.mod(2 * np.pi * omega_rpm / 60.0 * t + 0.3, 2 * np.pi)
    if runout:
        e = e + runout * np.column_stack([np.cos(phi) + 0.3 * np.sin(2 * phi),
                                          0.8 * np.sin(phi) - 0.2 * np.cos(2 * phi)])
    cols = {"t": t, "r_x": r[:, 0], "r_y": r[:, 1], "u_x": u[:, 0], "u_y": u[:, 1],
            "e_x": e[:, 0], "e_y": e[:, 1], "phi": phi}
    return Record(cols, FS, {"omega_rpm": omega_rpm, "p_inj_bar": p_inj_bar, "kind": kind},
                  f"sim-{kind}-{seed}.csv")
