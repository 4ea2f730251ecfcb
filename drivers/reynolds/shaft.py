"""Flexible shaft of the physics-grade plant: Euler–Bernoulli finite elements, modal reduction.

Per bending plane (x–z and y–z, identical), nodes carry (w, w') — deflection and slope. The
shaft (steel) is pinned radially by the ball bearing (a spring, no moment stiffness) at one end,
carries the gas-bearing journal sleeve and, at the other end, the disc (mass, diametral and
polar inertia, gyroscopic moment at Ω; mass unbalance). The gas film is not part of the
structure: its force enters at the journal node. Both planes use the same undamped modes
(``n_modes`` lowest, the zero-frequency pivoting mode about the ball bearing included); the
disc's gyroscopic moment couples the planes in modal coordinates::

    q̈ + (D_r + Ω G_r) q̇ + K_r q = Φᵀ f,      q = [q_x, q_y]                         (S1)

with G_r = [[0, g], [−g, 0]], g = I_p φ'_d φ'_dᵀ (φ'_d: modal slopes at the disc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la

STEEL_E = 210e9        # Pa
STEEL_RHO = 7850.0     # kg/m³


@dataclass(frozen=True)
class ShaftGeometry:
    """Rig dimensions (m, kg) — plausible values for a rig like the paper's Fig. 1."""

    length: float = 0.47            # shaft length
    diameter: float = 0.030         # shaft diameter (= journal diameter)
    z_ball: float = 0.02            # ball bearing, from the shaft end opposite the disc
    z_journal: float = 0.38         # gas-bearing journal centre
    z_disc: float = 0.45            # disc position (sensors here)
    k_ball: float = 2.0e8           # ball bearing radial stiffness, N/m
    c_ball: float = 200.0           # ball bearing radial damping, N s/m
    journal_mass: float = 0.0       # extra mass at the journal (a sleeve), kg
    disc_diameter: float = 0.16
    disc_thickness: float = 0.03
    modal_damping: float = 0.005    # structural damping ratio of every mode
    n_elements: int = 24
    n_modes: int = 4                # per plane

    @property
    def disc_mass(self) -> float:
        return STEEL_RHO * math.pi * (self.disc_diameter / 2) ** 2 * self.disc_thickness

    @property
    def disc_ip(self) -> float:
        """Polar moment of inertia of the disc, kg m²."""
        return 0.5 * self.disc_mass * (self.disc_diameter / 2) ** 2

    @property
    def disc_id(self) -> float:
        """Diametral moment of inertia of the disc, kg m²."""
        r = self.disc_diameter / 2
        return self.disc_mass * (3 * r * r + self.disc_thickness ** 2) / 12.0


@dataclass
class ShaftModel:
    """Modal model of one plane plus the coupling data (arrays in SI units)."""

    geometry: ShaftGeometry
    omega_r: np.ndarray            # modal natural frequencies (structure alone), rad/s
    phi_journal: np.ndarray        # modal deflection at the journal (n_modes,)
    phi_disc: np.ndarray           # modal deflection at the disc
    phi_disc_slope: np.ndarray     # modal slope at the disc
    d_r: np.ndarray                # modal damping matrix of one plane (n_modes × n_modes)
    weight_r: np.ndarray = field(repr=False, default=None)   # Φᵀ M 1: modal force per m/s²
    z_nodes: np.ndarray = field(repr=False, default=None)
    shapes: np.ndarray = field(repr=False, default=None)

    @property
    def n_modes(self) -> int:
        return self.omega_r.size

    def matrices(self, omega_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """(C_r, K_r) of (S1) for both planes at shaft speed Ω (rad/s)."""
        n = self.n_modes
        g = self.geometry.disc_ip * np.outer(self.phi_disc_slope, self.phi_disc_slope)
        C = np.zeros((2 * n, 2 * n))
        C[:n, :n] = self.d_r
        C[n:, n:] = self.d_r
        C[:n, n:] = omega_rad * g
        C[n:, :n] = -omega_rad * g
        K = np.diag(np.tile(self.omega_r ** 2, 2))
        return C, K

    def static_force(self, gravity_m_s2: float, disc_n=(0.0, 0.0)) -> np.ndarray:
        """Constant modal force (both planes, 2n) of gravity along −y and a disc force (N).

        Gravity: the consistent FE mass (shaft, disc, sleeve) under a uniform acceleration
        −g e_y, projected on the kept modes; the disc force through the modal deflections at
        the disc.
        """
        n = self.n_modes
        f = np.zeros(2 * n)
        f[:n] = self.phi_disc * disc_n[0]
        f[n:] = self.phi_disc * disc_n[1] - gravity_m_s2 * self.weight_r
        return f

    def rigid(self) -> np.ndarray:
        """Indices of the zero-frequency modes of one plane (pivoting about the ball bearing)."""
        return np.flatnonzero(self.omega_r < 1.0)

    def coupling(self) -> tuple[np.ndarray, np.ndarray]:
        """(Φ_b, Φ_d): 2 × 2n maps from q to (x, y) at the journal and at the disc."""
        n = self.n_modes
        Pb = np.zeros((2, 2 * n))
        Pd = np.zeros((2, 2 * n))
        Pb[0, :n] = self.phi_journal
        Pb[1, n:] = self.phi_journal
        Pd[0, :n] = self.phi_disc
        Pd[1, n:] = self.phi_disc
        return Pb, Pd


def _node_of(z_nodes: np.ndarray, z: float) -> int:
    i = int(np.argmin(np.abs(z_nodes - z)))
    return i


def build_shaft(geo: ShaftGeometry | None = None) -> ShaftModel:
    """Assemble the FE model of one plane and reduce it to ``n_modes`` mass-normalised modes."""
    g = geo or ShaftGeometry()
    ne = g.n_elements
    # nodes: uniform, with the ball bearing, journal and disc positions snapped on nodes
    z = np.linspace(0.0, g.length, ne + 1)
    nn = ne + 1
    ndof = 2 * nn
    K = np.zeros((ndof, ndof))
    M = np.zeros((ndof, ndof))
    A = math.pi * g.diameter ** 2 / 4
    EI = STEEL_E * math.pi * g.diameter ** 4 / 64
    for e in range(ne):
        le = z[e + 1] - z[e]
        k = EI / le ** 3 * np.array([[12, 6 * le, -12, 6 * le],
                                     [6 * le, 4 * le ** 2, -6 * le, 2 * le ** 2],
                                     [-12, -6 * le, 12, -6 * le],
                                     [6 * le, 2 * le ** 2, -6 * le, 4 * le ** 2]])
        m = STEEL_RHO * A * le / 420 * np.array([[156, 22 * le, 54, -13 * le],
                                                 [22 * le, 4 * le ** 2, 13 * le, -3 * le ** 2],
                                                 [54, 13 * le, 156, -22 * le],
                                                 [-13 * le, -3 * le ** 2, -22 * le, 4 * le ** 2]])
        idx = np.arange(2 * e, 2 * e + 4)
        K[np.ix_(idx, idx)] += k
        M[np.ix_(idx, idx)] += m
    nb = _node_of(z, g.z_ball)
    nj = _node_of(z, g.z_journal)
    nd = _node_of(z, g.z_disc)
    K[2 * nb, 2 * nb] += g.k_ball
    M[2 * nj, 2 * nj] += g.journal_mass
    M[2 * nd, 2 * nd] += g.disc_mass
    M[2 * nd + 1, 2 * nd + 1] += g.disc_id
    w2, V = la.eigh(K, M)
    w2 = np.clip(w2, 0.0, None)
    nm = g.n_modes
    V = V[:, :nm]
    for r in range(nm):                       # sign: positive deflection at the disc
        if V[2 * nd, r] < 0:
            V[:, r] = -V[:, r]
    om = np.sqrt(w2[:nm])
    Cb = np.zeros((ndof, ndof))
    Cb[2 * nb, 2 * nb] = g.c_ball
    D = V.T @ Cb @ V + np.diag(2 * g.modal_damping * om)
    t = np.zeros(ndof)
    t[0::2] = 1.0                             # a uniform translation of every node
    return ShaftModel(g, om, V[2 * nj].copy(), V[2 * nd].copy(), V[2 * nd + 1].copy(), D,
                      weight_r=V.T @ M @ t, z_nodes=z, shapes=V)
