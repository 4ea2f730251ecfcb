"""Compiled numerics of the gas film: finite-volume compressible Reynolds equation.

The film of the ``sim_reynolds`` plant (docs/plant.md, "Physics-grade plant"): isothermal,
compressible Reynolds equation in the journal gap, written for the cell mass (times R_g T)
``Ψ = p h A``::

    ∂(p h)/∂t + ∇·( −p h³/(12 μ) ∇p + (U/2) p h e_θ ) = R_g T ṁ_inj / A        (R1)

with h(θ, t) = c − x_b cos θ − y_b sin θ, U = Ω R, periodic in θ, p = p_a at the bearing ends.
Only the half bearing z ∈ [0, L/2] is solved (symmetry about the mid-plane: no journal tilt,
injectors in the mid-plane); forces are doubled.

Grid: ``n_theta`` cells in θ (index i), ``mz`` cells in z (index j, j = 0 at the mid-plane),
unknown k = i·mz + j. Face fluxes: central p_f, exact h_f at the face, gradients by two-point
differences; the θ-wedge term central (cell Péclet number ≪ 1 at these bearing numbers).

The time stepping (BDF2, Newton) is in :mod:`rigd_drivers.reynolds.step`, the linear
solver in :mod:`rigd_drivers.reynolds.solver`. Nothing allocates.
"""

from __future__ import annotations

import math

import numba

NV = 4               # valves / orifices
NR = 2 + NV          # low-rank columns: x_b, y_b, four orifices
H_MIN = 0.02         # film thickness floor, fraction of c (no contact model below it)

# geometry vector ``geo`` (float64) offsets
G_NT = 0             # n_theta
G_MZ = 1             # cells in the half length
G_R = 2              # journal radius, m
G_DTH = 3            # Δθ, rad
G_DZ = 4             # Δz, m
G_C = 5              # radial clearance c, m
G_MU = 6             # viscosity, Pa s
G_PA = 7             # ambient pressure, Pa abs
G_AREA = 8           # cell area R Δθ Δz, m²
G_RT = 9             # R_g T, J/kg
G_GAMMA = 10         # ratio of specific heats
G_CDA = 11           # Cd·A of a fully open valve, m² (the feed path's first restriction)
G_CDF = 12           # feed hole: C_d π d (inherent: × h = curtain) or C_d π d²/4 (orifice)
G_COMP = 13          # 1.0 inherent compensation, 0.0 orifice compensation
G_CAP = 14           # valve-to-hole chamber capacity V_c / (R_g T), kg/Pa
G_N = 15


@numba.njit(cache=True, nogil=True, inline="always")
def film_gap(c, xb, yb, cos_t, sin_t):
    """Film thickness (m) at angle θ (cos θ, sin θ) with the journal at (xb, yb) m, floored at
    ``H_MIN`` c (touchdown is not modelled: the film is kept finite)."""
    h = c - xb * cos_t - yb * sin_t
    if h < H_MIN * c:
        return H_MIN * c
    return h


@numba.njit(cache=True, nogil=True)
def orifice_flow(p_up, p_down, cda, rt, gam):
    """Isentropic orifice mass flow (kg/s) and its derivative d/dp_down.

    Choked below the critical pressure ratio, unchoked above; regularised linearly for
    pressure ratios above 0.995 (finite derivative at equal pressures); reverse flow by
    symmetry.
    """
    if cda <= 0.0:
        return 0.0, 0.0
    sgn = 1.0
    pu = p_up
    pd = p_down
    if pd > pu:
        sgn = -1.0
        pu = p_down
        pd = p_up
    r = pd / pu
    g1 = 1.0 / gam
    k_un = cda * pu * math.sqrt(2.0 * gam / ((gam - 1.0) * rt))
    r_lin = 0.995
    r1 = r ** g1                      # r^(1/γ): every power of r below is a product of it
    if r <= r1 * (2.0 / (gam + 1.0)):  # r^((γ−1)/γ) ≤ 2/(γ+1): at or below the critical ratio
        m = cda * pu * math.sqrt(gam / rt) * (2.0 / (gam + 1.0)) ** (
            (gam + 1.0) / (2.0 * (gam - 1.0)))
        dm_dr = 0.0
    elif r <= r_lin:
        a = r1 * r1 - r * r1          # r^(2/γ) − r^((γ+1)/γ)
        m = k_un * math.sqrt(a)
        da = (2.0 * g1) * (r1 * r1 / r) - ((gam + 1.0) * g1) * r1
        dm_dr = k_un * 0.5 * da / math.sqrt(a)
    else:
        rl1 = r_lin ** g1
        a = rl1 * rl1 - r_lin * rl1
        m0 = k_un * math.sqrt(a)
        m = m0 * (1.0 - r) / (1.0 - r_lin)
        dm_dr = -m0 / (1.0 - r_lin)
    # derivative with respect to p_down (the film side)
    if sgn > 0.0:
        return m, dm_dr / pu
    # reversed: film is upstream (pu = p_down); m(pu, pd) = pu·f(pd/pu)
    dm_dpu = m / pu - r * (dm_dr / pu)       # d(pu f(pd/pu))/dpu = f − r f'(r)
    return -m, -dm_dpu


@numba.njit(cache=True, nogil=True)
def film_force(geo, cs, p):
    """Film force on the journal (N, both halves): −∫ (p − p_a)(cos θ, sin θ) dA."""
    nt = int(geo[G_NT])
    mz = int(geo[G_MZ])
    pa = geo[G_PA]
    a2 = 2.0 * geo[G_AREA]
    fx = 0.0
    fy = 0.0
    for i in range(nt):
        s = 0.0
        for j in range(mz):
            s += p[i * mz + j] - pa
        fx -= a2 * s * cs[i]
        fy -= a2 * s * cs[nt + i]
    return fx, fy


@numba.njit(cache=True, nogil=True)
def film_mass(geo, cs, p, xb, yb):
    """Gas mass in the whole film × R_g T (Pa m³): Σ p h A, both halves."""
    nt = int(geo[G_NT])
    mz = int(geo[G_MZ])
    c = geo[G_C]
    s = 0.0
    for i in range(nt):
        h = c - xb * cs[i] - yb * cs[nt + i]
        for j in range(mz):
            s += p[i * mz + j] * h
    return 2.0 * s * geo[G_AREA]


@numba.njit(cache=True, nogil=True)
def film_rates(geo, cs, wts, p, xb, yb, omega, rate, out_flow, jA, jB, jC, dRx, dRy, pm,
               want_jac):
    """Net film mass rate (× R_g T, Pa m³/s) into each cell, at fixed geometry, without the
    injection (the feed path adds it: :mod:`rigd_drivers.reynolds.feed`).

    Parameters
    ----------
    geo : float64[G_N]
        Geometry and gas constants (offsets ``G_*``).
    cs : float64[4·n_theta]
        cos θ_i, sin θ_i at cell centres, cos, sin at the faces θ_{i+1/2}.
    wts : float64[NV·N]
        Orifice feed-patch weights (each row sums to 1).
    p : float64[N]
        Cell pressures, Pa abs.
    xb, yb : float
        Journal displacement at the bearing, m.
    omega : float
        Shaft speed, rad/s.
    rate : float64[N]
        Out: net rate into each cell.
    out_flow : float64[1]
        Out: mass flow (× R_g T) leaving through the bearing ends (both halves, Pa m³/s).
    jA, jB, jC : float64[n_theta, mz] / [n_theta, mz, mz] / [n_theta, mz]
        Out (if ``want_jac``): blocks of −∂rate/∂p: the lower and upper blocks are diagonal
        (stored as their diagonals), the diagonal block tridiagonal (stored dense).
    dRx, dRy : float64[N]
        Out (if ``want_jac``): −∂rate/∂x_b, −∂rate/∂y_b.
    pm : float64[NV]
        Out: mean pressure of each injector's feed patch, Pa.
    """
    nt = int(geo[G_NT])
    mz = int(geo[G_MZ])
    R = geo[G_R]
    dth = geo[G_DTH]
    dz = geo[G_DZ]
    c = geo[G_C]
    mu = geo[G_MU]
    pa = geo[G_PA]
    n = nt * mz
    for k in range(n):
        rate[k] = 0.0
    if want_jac:
        for i in range(nt):
            for a in range(mz):
                jA[i, a] = 0.0
                jC[i, a] = 0.0
                for b in range(mz):
                    jB[i, a, b] = 0.0
        for k in range(n):
            dRx[k] = 0.0
            dRy[k] = 0.0
    U = omega * R
    out_flow[0] = 0.0
    # θ faces: between cell i and i+1 (periodic), per z cell
    for i in range(nt):
        ip = i + 1 if i + 1 < nt else 0
        cf = cs[2 * nt + i]
        sf = cs[3 * nt + i]
        hf = film_gap(c, xb, yb, cf, sf)
        kf = hf * hf * hf * dz / (12.0 * mu * R * dth)
        uf = 0.5 * U * hf * dz
        dkf = 3.0 * hf * hf * dz / (12.0 * mu * R * dth)
        duf = 0.5 * U * dz
        for j in range(mz):
            a = i * mz + j
            b = ip * mz + j
            pa_ = p[a]
            pb_ = p[b]
            flux = -0.5 * kf * (pb_ * pb_ - pa_ * pa_) + 0.5 * uf * (pa_ + pb_)   # a → b
            rate[a] -= flux
            rate[b] += flux
            if want_jac:
                dfa = kf * pa_ + 0.5 * uf
                dfb = -kf * pb_ + 0.5 * uf
                # −∂rate_a/∂p = +∂flux/∂p ; −∂rate_b/∂p = −∂flux/∂p
                jB[i, j, j] += dfa
                jC[i, j] += dfb              # row a (block i), column b (block i+1)
                jB[ip, j, j] -= dfb
                jA[ip, j] -= dfa             # row b (block i+1), column a (block i)
                dflux_dh = -0.5 * dkf * (pb_ * pb_ - pa_ * pa_) + 0.5 * duf * (pa_ + pb_)
                dRx[a] += dflux_dh * (-cf)
                dRy[a] += dflux_dh * (-sf)
                dRx[b] -= dflux_dh * (-cf)
                dRy[b] -= dflux_dh * (-sf)
    # z faces (per θ cell; h uniform in z)
    for i in range(nt):
        ci = cs[i]
        si = cs[nt + i]
        h = film_gap(c, xb, yb, ci, si)
        kz = h * h * h * R * dth / (12.0 * mu * dz)
        dkz = 3.0 * h * h * R * dth / (12.0 * mu * dz)
        for j in range(mz - 1):
            a = i * mz + j
            b = a + 1
            flux = -0.5 * kz * (p[b] * p[b] - p[a] * p[a])
            rate[a] -= flux
            rate[b] += flux
            if want_jac:
                dfa = kz * p[a]
                dfb = -kz * p[b]
                jB[i, j, j] += dfa
                jB[i, j, j + 1] += dfb
                jB[i, j + 1, j + 1] -= dfb
                jB[i, j + 1, j] -= dfa
                dfh = -0.5 * dkz * (p[b] * p[b] - p[a] * p[a])
                dRx[a] += dfh * (-ci)
                dRy[a] += dfh * (-si)
                dRx[b] -= dfh * (-ci)
                dRy[b] -= dfh * (-si)
        # outer end: ambient at distance dz/2
        a = i * mz + mz - 1
        flux = -0.5 * 2.0 * kz * (pa * pa - p[a] * p[a])
        rate[a] -= flux
        out_flow[0] += 2.0 * flux
        if want_jac:
            jB[i, mz - 1, mz - 1] += 2.0 * kz * p[a]
            dfh = -0.5 * 2.0 * dkz * (pa * pa - p[a] * p[a])
            dRx[a] += dfh * (-ci)
            dRy[a] += dfh * (-si)
    # feed patches: mean pressure under each injector
    for v in range(NV):
        s = 0.0
        for k in range(n):
            s += wts[v * n + k] * p[k]
        pm[v] = s
