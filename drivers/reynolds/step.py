"""One BDF2 sub-step of the coupled film + shaft system, and the steady film.

The shaft unknowns are eliminated (x_b = C_b F(p) + x_known, with C_b = Φ_b S⁻¹ Φ_bᵀ and
S = α² I + α C_r + K_r, α = 3/(2 dt)); Newton on the film pressures is
:func:`rigd_drivers.reynolds.newton.newton_film`. A journal at the wall (ε ≥ 1) or a non-finite
solution stops the plant (:func:`rigd_drivers.reynolds.health.stop_plant`).
Nothing allocates (views into the kernel's arrays).
"""

from __future__ import annotations

import math

import numba

from rigd_drivers.reynolds.film import (
    G_AREA,
    G_C,
    G_N,
    H_MIN,
    NV,
    film_force,
    film_gap,
)
from rigd_drivers.reynolds.health import stop_plant
from rigd_drivers.reynolds.layout import (
    H_ACT,
    H_M,
    H_MZ,
    H_NT,
    O_CR,
    O_CS,
    O_FST,
    O_GEO,
    O_PHIB,
    O_PHID,
    O_SC,
    O_SINV,
    SC_ALPHA,
    SC_DT,
    SC_NEWTON,
    SC_NEWTON_MAX,
    SC_RES_TOL,
    ST_EPS_MAX,
    ST_FAIL,
    ST_HFLOOR,
    ST_MIN,
    ST_MOUT,
    ST_NSUB,
    ST_RES,
    ST_XB,
    STATUS_CONTACT,
    STATUS_DIVERGED,
    T_P,
    T_P1,
    T_P2,
    T_PC,
    T_PC1,
    T_PC2,
    T_PSI,
    T_PSI1,
    T_Q,
    T_Q1,
    T_SC,
    T_V,
    T_V1,
    W_HC,
    W_HIST,
    W_MD,
    W_OUT,
    W_RK,
    W_TMP,
)
from rigd_drivers.reynolds.newton import newton_film


@numba.njit(cache=True, nogil=True)
def substep(state, params, fdx, fdy):
    """One BDF2 sub-step of film + shaft with the disc force (fdx, fdy) N at the new time.

    The orifice area fractions must be in the work slot ``W_AF``. Updates p, Ψ, q, v and their
    histories, the cumulative in/out flows and the bearing displacement.
    """
    blk = int(params[H_ACT])
    nt = int(params[H_NT])
    mz = int(params[H_MZ])
    m = int(params[H_M])
    n = nt * mz
    sc = blk + int(params[O_SC])
    dt = params[sc + SC_DT]
    al = params[sc + SC_ALPHA]
    nit = int(params[sc + SC_NEWTON])
    ssc = int(params[T_SC])
    geo = params[blk + int(params[O_GEO]):blk + int(params[O_GEO]) + G_N]
    o = blk + int(params[O_CS])
    cs = params[o:o + 4 * nt]
    oq = int(params[T_Q])
    ov = int(params[T_V])
    oq1 = int(params[T_Q1])
    ov1 = int(params[T_V1])
    orr = int(params[W_RK])
    otmp = int(params[W_TMP])
    osinv = blk + int(params[O_SINV])
    ocr = blk + int(params[O_CR])
    ophib = blk + int(params[O_PHIB])
    ophid = blk + int(params[O_PHID])
    ofst = blk + int(params[O_FST])
    # a_q (in tmp), rk = α a_q + a_v + C_r a_q + Φ_dᵀ f_d + static load
    inv2 = 1.0 / (2.0 * dt)
    for r in range(m):
        state[otmp + r] = (4.0 * state[oq + r] - state[oq1 + r]) * inv2
    for r in range(m):
        av = (4.0 * state[ov + r] - state[ov1 + r]) * inv2
        acc = al * state[otmp + r] + av
        for s in range(m):
            acc += params[ocr + r * m + s] * state[otmp + s]
        acc += params[ophid + r] * fdx + params[ophid + m + r] * fdy + params[ofst + r]
        state[orr + r] = acc
    # x_known = Φ_b S⁻¹ rk
    xk0 = 0.0
    xk1 = 0.0
    for r in range(m):
        acc = 0.0
        for s in range(m):
            acc += params[osinv + r * m + s] * state[orr + s]
        state[otmp + m + r] = acc
        xk0 += params[ophib + r] * acc
        xk1 += params[ophib + m + r] * acc
    # film history and the Newton predictor: the quadratic through the last three time levels
    # (p_{n+1} ≈ 3 p_n − 3 p_{n−1} + p_{n−2}), kept where it stays above half the present p
    op = int(params[T_P])
    op1 = int(params[T_P1])
    ops = int(params[T_PSI])
    ops1 = int(params[T_PSI1])
    oh = int(params[W_HIST])
    op2 = int(params[T_P2])
    for k in range(n):
        state[oh + k] = (4.0 * state[ops + k] - state[ops1 + k]) * inv2
        pn = state[op + k]
        p1 = state[op1 + k]
        pr = 3.0 * (pn - p1) + state[op2 + k]      # quadratic through the last three levels
        state[op2 + k] = p1
        state[op1 + k] = pn
        if pr > 0.5 * pn:
            state[op + k] = pr
    opc = int(params[T_PC])
    opc1 = int(params[T_PC1])
    opc2 = int(params[T_PC2])
    ohc = int(params[W_HC])
    for v in range(NV):
        pn = state[opc + v]
        p1 = state[opc1 + v]
        state[ohc + v] = (4.0 * pn - p1) * inv2
        pr = 3.0 * (pn - p1) + state[opc2 + v]
        state[opc2 + v] = p1
        state[opc1 + v] = pn
        if pr > 0.5 * pn:
            state[opc + v] = pr
    tol = params[sc + SC_RES_TOL]
    res = newton_film(state, params, blk, al, True, xk0, xk1, nit,
                      int(params[sc + SC_NEWTON_MAX]), tol, al)
    state[ssc + ST_RES] = res
    state[ssc + ST_NSUB] += 1.0
    if not res < tol:
        state[ssc + ST_FAIL] += 1.0
    # final force, shaft update q = S⁻¹(Φ_bᵀ F + rk), v = α q − a_q
    p = state[op:op + n]
    fx, fy = film_force(geo, cs, p)
    for r in range(m):
        state[orr + r] += params[ophib + r] * fx + params[ophib + m + r] * fy
    xb = 0.0
    yb = 0.0
    for r in range(m):
        acc = 0.0
        for s in range(m):
            acc += params[osinv + r * m + s] * state[orr + s]
        aq = state[otmp + r]
        state[oq1 + r] = state[oq + r]
        state[ov1 + r] = state[ov + r]
        state[oq + r] = acc
        state[ov + r] = al * acc - aq
        xb += params[ophib + r] * acc
        yb += params[ophib + m + r] * acc
    c = geo[G_C]
    eps = math.sqrt(xb * xb + yb * yb) / c
    if not (res == res and eps < 1.0):
        # not finite, or the journal at the wall: stop at the last state before it
        stop_plant(state, params, ssc, STATUS_CONTACT if eps >= 1.0 else STATUS_DIVERGED)
        return
    if eps > state[ssc + ST_EPS_MAX]:
        state[ssc + ST_EPS_MAX] = eps
    if eps > 1.0 - H_MIN:               # the film thickness floor is reached somewhere
        state[ssc + ST_HFLOOR] += 1.0
    state[ssc + ST_XB] = xb
    state[ssc + ST_XB + 1] = yb
    # new film mass per cell, and the flows at the new time (for the mass balance)
    A = geo[G_AREA]
    for i in range(nt):
        h = film_gap(c, xb, yb, cs[i], cs[nt + i])
        for j in range(mz):
            k = i * mz + j
            state[ops1 + k] = state[ops + k]
            state[ops + k] = state[op + k] * h * A
    omd = int(params[W_MD])
    rt = geo[9]
    qin = 0.0
    for v in range(NV):
        qin += rt * state[omd + v]
    state[ssc + ST_MIN] += qin * dt
    state[ssc + ST_MOUT] += state[int(params[W_OUT])] * dt


@numba.njit(cache=True, nogil=True)
def steady_film(state, params, xb, yb, nit, tol, frozen):
    """Steady film (no time term) at the fixed bearing displacement (xb, yb) m, in place on the
    state's pressures; orifice areas from the work slot ``W_AF``. The chambers are at their
    steady state too, or held at their current pressures with ``frozen`` (the film's
    response faster than the chambers'). Returns the last update."""
    blk = int(params[H_ACT])
    n = int(params[H_NT]) * int(params[H_MZ])
    oh = int(params[W_HIST])
    for k in range(n):
        state[oh + k] = 0.0
    oh = int(params[W_HC])
    opc = int(params[T_PC])
    c0c = 1e15 if frozen else 0.0           # × cap ≫ any flow derivative: p_c stays put
    for v in range(NV):
        state[oh + v] = c0c * state[opc + v]
    return newton_film(state, params, blk, 0.0, False, xb, yb, nit, nit, tol, c0c)
