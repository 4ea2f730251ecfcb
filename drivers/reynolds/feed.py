"""Compiled feed path of the physics-grade plant: valve → chamber → feed hole → film.

Each of the four injectors (docs/plant.md, "Feed path") is two restrictions in series with a
gas volume between them::

    supply P_s ──valve (C_d A_v·a(y_p))──▶ chamber V_c, p_c ──feed hole──▶ film patch p̄

* the valve: an isentropic orifice of area C_d A_v times the valve's area fraction;
* the feed hole: ``inherent`` compensation — the curtain π d h_i (h_i the film thickness at
  the hole) — or ``orifice`` compensation — the hole's own section π d²/4;
* the chamber (isothermal, as the film): (V_c / R_g T) dp_c/dt = ṁ_v − ṁ_f.

Both restrictions choke (:func:`rigd_drivers.reynolds.film.orifice_flow`). The chamber
pressures are extra unknowns of the film's Newton step, eliminated per injector
(:func:`feed_flows` gives the flows and partial derivatives, :func:`chamber_eliminate` the
Schur complement). Nothing allocates.
"""

from __future__ import annotations

import math

import numba

from rigd_drivers.reynolds.film import (
    G_C,
    G_CAP,
    G_CDA,
    G_CDF,
    G_COMP,
    G_GAMMA,
    G_RT,
    H_MIN,
    NV,
    orifice_flow,
)

# valve i at θ_i = 90°, 0°, 270°, 180° (1 at +y, 2 at +x, 3 at −y, 4 at −x; Eq. 1's pairing)
VALVE_COS = (0.0, 1.0, 0.0, -1.0)
VALVE_SIN = (1.0, 0.0, -1.0, 0.0)

# per-injector work entries (``fw[4 v + ·]``)
F_MV = 0             # valve flow ṁ_v, kg/s
F_DMV = 1            # ∂ṁ_v/∂p_c
F_DMFC = 2           # ∂ṁ_f/∂p_c
F_DMFH = 3           # ∂ṁ_f/∂h_i (inherent only)
NFW = 4


@numba.njit(cache=True, nogil=True)
def restriction_flow(p_up, p_down, cda, rt, gam):
    """Isentropic flow through a restriction (kg/s) and its partials (∂/∂p_up, ∂/∂p_down).

    The flow is homogeneous of degree one in the two pressures, so
    p_up ∂m/∂p_up + p_down ∂m/∂p_down = m (Euler) gives the upstream partial."""
    m, dmd = orifice_flow(p_up, p_down, cda, rt, gam)
    return m, (m - p_down * dmd) / p_up, dmd


@numba.njit(cache=True, nogil=True)
def feed_hole_area(geo, h):
    """C_d × area of a feed hole at film thickness h (m): the curtain or the hole section."""
    if geo[G_COMP] != 0.0:
        hh = h if h > H_MIN * geo[G_C] else H_MIN * geo[G_C]
        return geo[G_CDF] * hh
    return geo[G_CDF]


@numba.njit(cache=True, nogil=True)
def feed_flows(geo, pm, pc, xb, yb, p_sup, afrac, mdot, dmdot, fw):
    """Flows of the four injectors at the patch mean pressures ``pm`` and chamber pressures
    ``pc`` (Pa), journal at (xb, yb) m.

    Writes ṁ_f (into the film, kg/s) to ``mdot``, ∂ṁ_f/∂p̄ to ``dmdot`` and the valve flow and
    the remaining partials to ``fw`` (``F_*`` entries per injector).
    """
    rt = geo[G_RT]
    gam = geo[G_GAMMA]
    c = geo[G_C]
    for v in range(NV):
        h = c - xb * VALVE_COS[v] - yb * VALVE_SIN[v]
        mv, _, dmv = restriction_flow(p_sup, pc[v], afrac[v] * geo[G_CDA], rt, gam)
        af = feed_hole_area(geo, h)
        mf, dmfc, dmfp = restriction_flow(pc[v], pm[v], af, rt, gam)
        mdot[v] = mf
        dmdot[v] = dmfp
        o = NFW * v
        fw[o + F_MV] = mv
        fw[o + F_DMV] = dmv
        fw[o + F_DMFC] = dmfc
        dh = 0.0
        if geo[G_COMP] != 0.0 and h > H_MIN * c:
            dh = mf / h                      # the flow is proportional to the curtain area
        fw[o + F_DMFH] = dh


@numba.njit(cache=True, nogil=True)
def chamber_eliminate(geo, c0, pc, hist, mdot, dmdot, fw, res, gch):
    """Eliminate the chamber pressures from one Newton step (Schur complement per injector).

    Chamber residual r_c = cap (c0 p_c − hist) − ṁ_v + ṁ_f (c0 = 3/(2 dt) for BDF2, 0 for
    the steady state), g = ∂r_c/∂p_c. The film then sees the effective source
    ṁ_f − (∂ṁ_f/∂p_c) r_c / g and the derivatives (∂ṁ_f/∂p̄, ∂ṁ_f/∂h) scaled by
    s = 1 − (∂ṁ_f/∂p_c)/g: ``mdot``, ``dmdot`` and ``fw[F_DMFH]`` are overwritten with them;
    ``res``/``gch`` keep r_c and g for :func:`chamber_update`.
    """
    cap = geo[G_CAP]
    for v in range(NV):
        o = NFW * v
        r = cap * (c0 * pc[v] - hist[v]) - fw[o + F_MV] + mdot[v]
        g = cap * c0 - fw[o + F_DMV] + fw[o + F_DMFC]
        if g <= 0.0 or not math.isfinite(g):
            g = 1e-30
        res[v] = r
        gch[v] = g
        s = 1.0 - fw[o + F_DMFC] / g
        mdot[v] = mdot[v] - fw[o + F_DMFC] * r / g
        # the raw ∂ṁ_f/∂p̄ is needed by chamber_update: keep it in F_DMV (ṁ_v's is used up)
        fw[o + F_DMV] = dmdot[v]
        dmdot[v] = s * dmdot[v]
        fw[o + F_MV] = fw[o + F_DMFH]                  # raw ∂ṁ_f/∂h, for the update too
        fw[o + F_DMFH] = s * fw[o + F_DMFH]


@numba.njit(cache=True, nogil=True)
def chamber_update(geo, pc, dpm, dxb, dyb, fw, res, gch, p_floor):
    """Chamber pressure update from the film's Newton update: δp_c = −(r_c + ∂ṁ_f/∂p̄ δp̄ +
    ∂ṁ_f/∂h δh)/g, δh = −cos θ_i δx_b − sin θ_i δy_b. Returns the largest |δp_c| (Pa)."""
    upd = 0.0
    for v in range(NV):
        o = NFW * v
        dh = -dxb * VALVE_COS[v] - dyb * VALVE_SIN[v]
        d = -(res[v] + fw[o + F_DMV] * dpm[v] + fw[o + F_MV] * dh) / gch[v]
        pn = pc[v] + d
        if pn < p_floor:
            pn = p_floor
        if abs(pn - pc[v]) > upd:
            upd = abs(pn - pc[v])
        pc[v] = pn
    return upd


@numba.njit(cache=True, nogil=True)
def add_sources(geo, wts, mdot, fw, rate, dRx, dRy, want_jac):
    """Add the injection (half of each ṁ_f into the half film, spread by the patch weights) to
    the film rates, and its dependence on the journal position (curtain area) to −∂rate/∂x_b.
    """
    n = rate.shape[0]
    rt = geo[G_RT]
    for v in range(NV):
        dmh = fw[NFW * v + F_DMFH]
        for k in range(n):
            w = wts[v * n + k]
            if w != 0.0:
                rate[k] += 0.5 * rt * mdot[v] * w
                if want_jac:
                    dRx[k] += 0.5 * rt * w * dmh * VALVE_COS[v]
                    dRy[k] += 0.5 * rt * w * dmh * VALVE_SIN[v]
