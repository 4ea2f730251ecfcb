"""The rotor rig's grey-box sub-models of the paper, on the mechanical structure
(:class:`rigd.ident.greybox.mechanical.MechanicalStructure`, Eqs. 4-6):

* :func:`bearing_structure` — 𝔐_b (Eqs. 5-7): valve positions u → rotor displacements e;
* :func:`actuator_structure` — 𝔐_a (Eqs. 8-10): commanded references r → valve positions u,
  decoupled second-order valves (:class:`ActuatorStructure`, its read-outs per axis).
"""

from __future__ import annotations

import numpy as np

from rigd.ident.greybox.mechanical import MechanicalStructure


class ActuatorStructure(MechanicalStructure):
    """𝔐_a (Eqs. 8-10): decoupled second-order valves, u_j = κ_j p1 p2 /((s+p1)(s+p2)) r_j.

    Per axis: ü + d_a u̇ + k_a u = b_a r, so k_a = p1 p2, d_a = p1 + p2, b_a = κ k_a.
    """

    def readouts(self, theta):
        K, D, B, _, _ = self.unpack(theta)
        out = {"axes": {}}
        for i, ax in enumerate(("x", "y")[:self.n]):
            k, d, b = K[i, i], D[i, i], B[i, i]
            roots = np.roots([1.0, d, k])
            poles = sorted((-roots).tolist(), key=lambda z: abs(z))
            poles = [float(p.real) if abs(complex(p).imag) < 1e-9 else complex(p) for p in poles]
            ent = {"gain": float(b / k) if k != 0 else float("nan"),
                   "f_n_hz": float(np.sqrt(abs(k)) / (2 * np.pi)),
                   "zeta": float(d / (2 * np.sqrt(abs(k)))) if k != 0 else float("nan")}
            if all(isinstance(p, float) for p in poles):
                ent["poles_rad_s"] = poles
            else:
                ent["poles_rad_s"] = [str(p) for p in poles]
            out["axes"][ax] = ent
        return out


def bearing_structure(hold: str = "zoh") -> MechanicalStructure:
    """𝔐_b (Eqs. 5-7): u = [u_x, u_y] (V) -> p = [e_x, e_y] (µm), 20 parameters.

    ``hold``: how the input behaves between samples. u is a *measured* valve position (a
    continuous signal), for which ``"foh"`` (linear between samples) is right and is what
    ``rigd identify`` uses (:data:`rigd.ident.greybox.submodels.DEFAULT_HOLD`); the plain
    default ``"zoh"`` is the raw simulator convention (inputs held), kept for callers that
    compensate themselves.
    """
    full = np.ones((2, 2), bool)
    return MechanicalStructure("bearing", full, full, full, full, "", ["x", "y"], ["x", "y"],
                               ["u_x", "u_y"], ["e_x", "e_y"], x0_name="x0_", hold=hold)


def actuator_structure(hold: str = "zoh") -> ActuatorStructure:
    """𝔐_a (Eqs. 8-10): r = [r_x, r_y] (V) -> u = [u_x, u_y] (V), 12 parameters.

    r is the commanded reference, held over each loop period (zero-order hold).
    """
    eye = np.eye(2, dtype=bool)
    return ActuatorStructure("actuator", eye, eye, eye, eye, "a_", ["x", "y"], ["x", "y"],
                             ["r_x", "r_y"], ["u_x", "u_y"], x0_name="xa0_", hold=hold)
