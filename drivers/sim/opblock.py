"""The operating-point part of the simulated plant's parameter block, compiled without the GIL.

An operating-point change while the 5 kHz loop runs is prepared in the caller's thread
(:meth:`rigd_drivers.plant.base.SimulatedPlantDriver.prepare_operating_point`). Every moment
that thread holds the GIL, the loop thread may have to wait for it when it wakes for its next
cycle, and a GIL hand-over costs up to the switch interval (200 µs, one period) plus a
wake-up: an overrun (docs/loop.md, bench figure ``op_change_miss_fraction``). The Python and
numpy glue around the matrix exponentials (balancing, block assembly, about 150 µs per change)
held it; here all of it runs in one compiled call with the GIL released:

* the bearing matrices of Eq. 4 (:func:`rigd_drivers.plant.physics.bearing_core`);
* the first-order-hold discretisation of the augmented bearing for one period and for one
  sub-step (the same Van Loan block and power-of-two balancing as :func:`rigd.lti.foh`);
* the block entries that depend on (Ω, P_I): Φ/G0/G1 (period and sub-step), the cubic
  stiffness (its ratio to the mean film stiffness), the unbalance force, Ω and P_I.

Everything else in the block does not depend on the operating point and comes from a
template built once per driver (:class:`rigd_drivers.sim.params.ParamBlocks`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rigd_drivers.plant.physics import GAP_UM, bearing_core
from rigd_drivers.sim import kernel as k
from rigd_drivers.sim.expm import expm


@njit(cache=True, nogil=True)
def _balance(A):
    """Powers of two s with ``A * s[None, :] / s[:, None]`` balanced (rows and columns of
    comparable 1-norm off the diagonal; Parlett & Reinsch 1969, as LAPACK's dgebal 'S')."""
    n = A.shape[0]
    At = A.copy()
    s = np.ones(n)
    done = False
    while not done:
        done = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(At[j, i])
                    r += abs(At[i, j])
            if c == 0.0 or r == 0.0:
                continue
            f = 1.0
            tot = c + r
            g = r / 2.0
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c >= g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * tot:
                done = False
                s[i] *= f
                for j in range(n):
                    At[i, j] /= f
                    At[j, i] *= f
    return s


@njit(cache=True, nogil=True)
def foh(A, B, dt):
    """First-order-hold discretisation (Φ, G0, G1) of ẋ = A x + B w, w linear between
    samples: ``x[k+1] = Φ x[k] + G0 w[k] + G1 w[k+1]`` (as :func:`rigd.lti.foh`; dt in s)."""
    nx, nu = A.shape[0], B.shape[1]
    s = _balance(A)
    At = np.empty((nx, nx))
    for i in range(nx):
        for j in range(nx):
            At[i, j] = A[i, j] * s[j] / s[i]
    na = np.max(np.abs(At))
    b = np.ones(nu)
    Bt = np.empty((nx, nu))
    for j in range(nu):
        nb = 0.0
        for i in range(nx):
            Bt[i, j] = B[i, j] / s[i]
            nb = max(nb, abs(Bt[i, j]))
        if nb > 0.0:
            b[j] = 2.0 ** np.round(np.log2(nb / (na if na > 0.0 else 1.0)))
        for i in range(nx):
            Bt[i, j] /= b[j]
    m = nx + 2 * nu
    M = np.zeros((m, m))
    M[:nx, :nx] = At * dt
    M[:nx, nx:nx + nu] = Bt * dt
    for j in range(nu):
        M[nx + j, nx + nu + j] = 1.0
    E = expm(M)
    Phi = np.empty((nx, nx))
    G0 = np.empty((nx, nu))
    G1 = np.empty((nx, nu))
    for i in range(nx):
        for j in range(nx):
            Phi[i, j] = E[i, j] * (s[i] / s[j])
        for j in range(nu):
            back = s[i] * b[j]
            g1 = E[i, nx + j] * back
            g2 = E[i, nx + nu + j] * back
            G0[i, j] = g1 - g2
            G1[i, j] = g2
    return Phi, G0, G1


@njit(cache=True, nogil=True)
def fill_operating_point(b, A_aug, B_aug, omega_rpm, p_inj_bar, T, n_sub, k3_ratio,
                         unbalance_g_mm):
    """Write the (Ω, P_I)-dependent entries of the parameter block ``b`` (float64[NA]).

    Parameters
    ----------
    b : float64[NA]
        The block; its operating-point-independent entries are already set (template).
    A_aug, B_aug : float64 (NX, NX), (NX, NW)
        The augmented bearing's continuous matrices with the extra mode's rows filled and
        zeros in the bearing part (``[:4, :4]``, ``[:4, :]``), which is written here.
    omega_rpm, p_inj_bar : float
        Ω (rpm), P_I (bar), range-checked by the caller.
    T : float
        Loop period, s.
    n_sub : int
        Sub-steps per period (cubic stiffness integration).
    k3_ratio : float
        Cubic film stiffness at the gap relative to the mean linear stiffness (0: off).
    unbalance_g_mm : float
        Mass unbalance, g·mm (0: none).

    Runs in: the preparing thread, without the GIL (allocates its scratch matrices).
    """
    M, D, G, K, B_p = bearing_core(omega_rpm, p_inj_bar)
    w_rad = omega_rpm * 2.0 * math.pi / 60.0
    A = A_aug.copy()
    B = B_aug.copy()
    for i in range(2):
        minv = 1.0 / M[i, i]
        A[i, 2 + i] = 1.0
        for j in range(2):
            A[2 + i, j] = -(minv * K[i, j])
            A[2 + i, 2 + j] = -(minv * (D[i, j] - w_rad * G[i, j]))
            B[2 + i, j] = minv * B_p[i, j]
        B[2 + i, 2 + i] = 1e6 * minv
    nx2, nxw = k.NX * k.NX, k.NX * k.NW
    Phi, G0, G1 = foh(A, B, T)
    b[k.A_PHI:k.A_PHI + nx2] = Phi.ravel()
    b[k.A_G0:k.A_G0 + nxw] = G0.ravel()
    b[k.A_G1:k.A_G1 + nxw] = G1.ravel()
    Phi, G0, G1 = foh(A, B, T / n_sub)
    b[k.A_SPHI:k.A_SPHI + nx2] = Phi.ravel()
    b[k.A_SG0:k.A_SG0 + nxw] = G0.ravel()
    b[k.A_SG1:k.A_SG1 + nxw] = G1.ravel()
    if k3_ratio != 0.0:
        k_mean = 1e-6 * ((K[0, 0] + K[1, 1]) / 2.0)          # N/µm
        b[k.A_K3] = k3_ratio * k_mean / GAP_UM ** 2
    if unbalance_g_mm != 0.0:
        b[k.A_UNB] = unbalance_g_mm * 1e-6 * w_rad ** 2        # N
    b[k.A_OMEGA_RAD] = w_rad
    b[k.A_OMEGA_RPM] = omega_rpm
    b[k.A_PINJ] = p_inj_bar
