"""Linearised analysis of the physics-grade plant (Python around the kernels).

The semi-discrete film + feed chambers + shaft ODE at the rest state of
:mod:`rigd_drivers.reynolds.analysis`, its lightly damped modes, and the classical
small-eccentricity reference of a self-acting gas journal bearing (Ausman 1961).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds.analysis import PlantArrays
from rigd_drivers.reynolds.feed import NFW, add_sources, feed_flows
from rigd_drivers.reynolds.film import G_AREA, G_C, G_CAP, NV, film_force, film_rates


# --- linearised coupled system --------------------------------------------------------------
def _rates(pa: PlantArrays, p, pc, xb, yb, afrac):
    """Film rates with the injection at chamber pressures ``pc``, and the chamber rates
    (kg/s into each chamber)."""
    n = pa.n
    nt, mz = pa.lay.nt, pa.lay.mz
    rate = np.zeros(n)
    outf = np.zeros(1)
    z3 = np.zeros((nt, mz, mz))
    z2 = np.zeros((nt, mz))
    zn = np.zeros(n)
    md = np.zeros(NV)
    dmd = np.zeros(NV)
    pm = np.zeros(NV)
    fw = np.zeros(NFW * NV)
    sc = pa.scalars
    film_rates(pa.geo, pa.cs, pa.wts, p, xb, yb, sc[L.SC_OMEGA_RAD], rate, outf, z2, z3, z2,
               zn, zn, pm, False)
    feed_flows(pa.geo, pm, np.asarray(pc, float), xb, yb, sc[L.SC_PSUP],
               np.asarray(afrac, float), md, dmd, fw)
    add_sources(pa.geo, pa.wts, md, fw, rate, zn, zn, False)
    return rate, fw[0::NFW] - md


def ode_rhs(pa: PlantArrays, y: np.ndarray, afrac) -> np.ndarray:
    """Semi-discrete ODE of film + feed chambers + shaft, y = [p (N), p_c (4), q (m), v (m)],
    under the static load."""
    n, m = pa.n, pa.lay.m
    nt = pa.lay.nt
    p, pc, q, v = y[:n], y[n:n + NV], y[n + NV:n + NV + m], y[n + NV + m:]
    Pb, _ = pa.shaft.coupling()
    C, K = pa.shaft.matrices(pa.scalars[L.SC_OMEGA_RAD])
    xb = Pb @ q
    vb = Pb @ v
    rate, chamber = _rates(pa, p, pc, xb[0], xb[1], afrac)
    cs = pa.cs
    A = pa.geo[G_AREA]
    h = pa.geo[G_C] - xb[0] * cs[:nt] - xb[1] * cs[nt:2 * nt]
    hdot = -vb[0] * cs[:nt] - vb[1] * cs[nt:2 * nt]
    mz = pa.lay.mz
    H = np.repeat(h, mz)
    Hd = np.repeat(hdot, mz)
    pdot = (rate - p * A * Hd) / (H * A)
    pcdot = chamber / pa.geo[G_CAP]
    fx, fy = film_force(pa.geo, pa.cs, np.ascontiguousarray(p))
    vdot = -C @ v - K @ q + Pb.T @ np.array([fx, fy]) + pa.params_block(L.O_FST, m)
    return np.concatenate([pdot, pcdot, v, vdot])


@dataclass
class LinearModes:
    """Lightly damped modes of the linearised plant at its equilibrium."""

    def of_axis(self, axis: str) -> int:
        """Index of the lowest mode whose disc motion is mostly along ``axis`` ("x"/"y")."""
        i = 0 if axis == "x" else 1
        for j in range(self.freq_hz.size):
            if abs(self.disc[i, j]) > abs(self.disc[1 - i, j]):
                return j
        raise ValueError(f"no mode along {axis}")

    freq_hz: np.ndarray
    zeta: np.ndarray
    forward: np.ndarray          # True: forward whirl at the disc
    disc: np.ndarray | None = None   # complex (x, y) amplitude at the disc, 2 × modes


def linear_modes(pa: PlantArrays, afrac, *, f_max_hz: float = 1000.0) -> LinearModes:
    """Eigen-analysis of the linearised film + shaft system at the current equilibrium.

    The film pressures and journal position must be at rest (:func:`rest`). Returns the
    oscillatory modes below ``f_max_hz`` with damping ratio < 0.5, sorted by frequency.
    """
    n, m = pa.n, pa.lay.m
    o = pa.lay.st
    y0 = np.concatenate([pa.p.copy(), pa.pc.copy(), pa.state[o[L.T_Q]:o[L.T_Q] + m],
                         np.zeros(m)])
    N = y0.size
    J = np.zeros((N, N))
    for j in range(N):
        if j < n + NV:
            d = 1e-6 * pa.geo[7]
        elif j < n + NV + m:
            d = 1e-10
        else:
            d = 1e-7
        yp = y0.copy()
        yp[j] += d
        ym = y0.copy()
        ym[j] -= d
        J[:, j] = (ode_rhs(pa, yp, afrac) - ode_rhs(pa, ym, afrac)) / (2 * d)
    lam, V = np.linalg.eig(J)
    _, Pd = pa.shaft.coupling()
    sel = (lam.imag > 0) & (lam.imag / (2 * math.pi) < f_max_hz)
    lam, V = lam[sel], V[:, sel]
    z = -lam.real / np.abs(lam)
    keep = z < 0.5
    lam, V, z = lam[keep], V[:, keep], z[keep]
    order = np.argsort(lam.imag)
    lam, V, z = lam[order], V[:, order], z[order]
    disc = Pd @ V[n + NV:n + NV + m]                      # complex (x, y) amplitude at the disc
    # forward whirl: y lags x by +90° for e^{iωt}: y ≈ −i x  →  Im(conj(x)·y) < 0
    fwd = np.imag(np.conj(disc[0]) * disc[1]) < 0
    return LinearModes(lam.imag / (2 * math.pi), z, fwd, disc)


# --- classical reference ---------------------------------------------------------------------
def ausman_stiffness(radius_m: float, length_m: float, clearance_m: float, mu: float,
                     p_a: float, omega_rad: float) -> np.ndarray:
    """Small-eccentricity stiffness (N/m) of a plain self-acting gas journal bearing.

    First-order perturbation of the steady compressible Reynolds equation about the concentric
    position (Ausman 1961, "An improved analytical solution for self-acting, gas-lubricated
    journal bearings of finite length", J. Basic Eng. 83; the "linearised ph" solution in its
    ε → 0 limit). With Λ = 6μΩR²/(p_a c²), ℓ = L/(2R), κ = √(1 + iΛ)::

        p = p_a (1 + ε Re[g(ζ) e^{iθ}]),  g = iΛ/(1 + iΛ) (1 − cosh κζ / cosh κℓ)

    and K = −∂F/∂e; returns [[k_xx, k_xy], [k_yx, k_yy]] (isotropic: k_yy = k_xx,
    k_xy = −k_yx).
    """
    lam = 6 * mu * omega_rad * radius_m ** 2 / (p_a * clearance_m ** 2)
    ell = length_m / (2 * radius_m)
    kap = np.sqrt(1 + 1j * lam)
    gint = 1j * lam / (1 + 1j * lam) * (2 * ell - 2 * np.tanh(kap * ell) / kap) * radius_m
    # F_x = −p_a ε π R Re(gint), F_y = +p_a ε π R Im(gint), for e_x = ε c
    kxx = p_a * math.pi * radius_m * gint.real / clearance_m
    kyx = -p_a * math.pi * radius_m * gint.imag / clearance_m
    return np.array([[kxx, -kyx], [kyx, kxx]])
