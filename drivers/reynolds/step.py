"""One BDF2 sub-step of the coupled film + shaft system, and the film's Newton solver.

The shaft unknowns are eliminated (x_b = C_b F(p) + x_known, with C_b = Φ_b S⁻¹ Φ_bᵀ and
S = α² I + α C_r + K_r, α = 3/(2 dt)); Newton on the film pressures solves the
block-cyclic-tridiagonal film Jacobian (:func:`rigd_drivers.reynolds.solver.block_cyclic_solve`)
with the shaft (rank 2) and the four orifices (rank 4) as a Sherman–Morrison–Woodbury update.
Nothing allocates (views into the kernel's arrays).
"""

from __future__ import annotations

import numba

from rigd_drivers.reynolds.feed import (
    NFW,
    add_sources,
    chamber_eliminate,
    chamber_update,
    feed_flows,
)
from rigd_drivers.reynolds.film import (
    G_AREA,
    G_C,
    G_N,
    H_MIN,
    NR,
    NV,
    film_force,
    film_rates,
)
from rigd_drivers.reynolds.layout import (
    H_ACT,
    H_M,
    H_MZ,
    H_NT,
    O_CB,
    O_CR,
    O_CS,
    O_FST,
    O_GEO,
    O_PHIB,
    O_PHID,
    O_SC,
    O_SINV,
    O_WTS,
    SC_ALPHA,
    SC_DT,
    SC_NEWTON,
    SC_OMEGA_RAD,
    SC_PSUP,
    ST_FAIL,
    ST_MIN,
    ST_MOUT,
    ST_RES,
    ST_XB,
    T_P,
    T_P1,
    T_PC,
    T_PC1,
    T_PSI,
    T_PSI1,
    T_Q,
    T_Q1,
    T_SC,
    T_V,
    T_V1,
    W_AF,
    W_CAP,
    W_CAPI,
    W_D,
    W_DINV,
    W_DMD,
    W_DRX,
    W_DRY,
    W_E,
    W_FB,
    W_FW,
    W_G,
    W_GC,
    W_GV,
    W_HC,
    W_HIST,
    W_JA,
    W_JB,
    W_JC,
    W_MD,
    W_OUT,
    W_PM,
    W_RATE,
    W_RC,
    W_RK,
    W_T1,
    W_T2,
    W_TMP,
    W_VR,
)
from rigd_drivers.reynolds.solver import block_cyclic_solve, inv_small


@numba.njit(cache=True, nogil=True)
def newton_film(state, params, blk, c0, dt_on, xk0, xk1, nit, tol, c0c):
    """Newton iterations for the film pressures (state's current p, in place).

    Residual R = c0·p h A − hist − rate(p, x_b(p)), x_b = Cb F(p) + xk (c0 = 3/(2dt), BDF2;
    c0 = 0 and Cb ignored with ``dt_on`` false: steady film at the fixed x_b = xk).
    The chamber pressures of the feed path are unknowns too (eliminated per injector,
    :mod:`rigd_drivers.reynolds.feed`; their time factor ``c0c`` — ``c0`` but for
    :func:`steady_film`'s frozen chambers — and history in ``W_HC``).
    Returns the last relative update max(‖δp‖∞, ‖δp_c‖∞) / p_a.
    """
    nt = int(params[H_NT])
    mz = int(params[H_MZ])
    n = nt * mz
    geo = params[blk + int(params[O_GEO]):blk + int(params[O_GEO]) + G_N]
    o = blk + int(params[O_CS])
    cs = params[o:o + 4 * nt]
    o = blk + int(params[O_WTS])
    wts = params[o:o + NV * n]
    o = blk + int(params[O_CB])
    cb00 = params[o]
    cb01 = params[o + 1]
    cb10 = params[o + 2]
    cb11 = params[o + 3]
    if not dt_on:
        cb00 = 0.0
        cb01 = 0.0
        cb10 = 0.0
        cb11 = 0.0
    sc = blk + int(params[O_SC])
    omega = params[sc + SC_OMEGA_RAD]
    psup = params[sc + SC_PSUP]
    o = int(params[T_P])
    p = state[o:o + n]
    o = int(params[W_RATE])
    rate = state[o:o + n]
    mm = mz * mz
    o = int(params[W_JA])
    jA = state[o:o + n].reshape((nt, mz))
    o = int(params[W_JB])
    jB = state[o:o + nt * mm].reshape((nt, mz, mz))
    o = int(params[W_JC])
    jC = state[o:o + n].reshape((nt, mz))
    o = int(params[W_DRX])
    dRx = state[o:o + n]
    o = int(params[W_DRY])
    dRy = state[o:o + n]
    nr1 = NR + 1
    o = int(params[W_D])
    d = state[o:o + n * nr1].reshape((nt, mz, nr1))
    o = int(params[W_DINV])
    Dinv = state[o:o + nt * mm].reshape((nt, mz, mz))
    o = int(params[W_E])
    E = state[o:o + nt * mm].reshape((nt, mz, mz))
    o = int(params[W_T1])
    T1 = state[o:o + mm].reshape((mz, mz))
    o = int(params[W_T2])
    T2 = state[o:o + mm].reshape((mz, mz))
    o = int(params[W_FB])
    Fb = state[o:o + mm].reshape((mz, mz))
    o = int(params[W_G])
    G = state[o:o + mm].reshape((mz, mz))
    o = int(params[W_GV])
    gv = state[o:o + mz * nr1].reshape((mz, nr1))
    o = int(params[W_MD])
    mdot = state[o:o + NV]
    o = int(params[W_DMD])
    dmdot = state[o:o + NV]
    o = int(params[W_AF])
    af = state[o:o + NV]
    o = int(params[W_OUT])
    outf = state[o:o + 1]
    o = int(params[W_CAP])
    cap = state[o:o + NR * NR].reshape((NR, NR))
    o = int(params[W_CAPI])
    capi = state[o:o + NR * NR].reshape((NR, NR))
    o = int(params[W_HIST])
    hist = state[o:o + n]
    o = int(params[W_VR])
    vr = state[o:o + 2 * NR]
    o = int(params[T_PC])
    pc = state[o:o + NV]
    o = int(params[W_HC])
    histc = state[o:o + NV]
    o = int(params[W_FW])
    fw = state[o:o + NFW * NV]
    o = int(params[W_RC])
    resc = state[o:o + NV]
    o = int(params[W_GC])
    gch = state[o:o + NV]
    o = int(params[W_PM])
    pm = state[o:o + NV]
    A = geo[G_AREA]
    c = geo[G_C]
    pa = geo[7]
    rt = geo[9]
    upd = 0.0
    for _ in range(nit):
        fx, fy = film_force(geo, cs, p)
        xb = cb00 * fx + cb01 * fy + xk0
        yb = cb10 * fx + cb11 * fy + xk1
        film_rates(geo, cs, wts, p, xb, yb, omega, rate, outf, jA, jB, jC, dRx, dRy, pm, True)
        feed_flows(geo, pm, pc, xb, yb, psup, af, mdot, dmdot, fw)
        chamber_eliminate(geo, c0c, pc, histc, mdot, dmdot, fw, resc, gch)
        add_sources(geo, wts, mdot, fw, rate, dRx, dRy, True)
        for i in range(nt):
            ci = cs[i]
            si = cs[nt + i]
            h = c - xb * ci - yb * si
            if h < H_MIN * c:
                h = H_MIN * c
            for j in range(mz):
                k = i * mz + j
                r = c0 * p[k] * h * A - hist[k] - rate[k]
                jB[i, j, j] += c0 * h * A
                dRx[k] += c0 * p[k] * A * (-ci)
                dRy[k] += c0 * p[k] * A * (-si)
                d[i, j, 0] = -r
                # low-rank columns U: shaft (through Cb), orifices
                d[i, j, 1] = dRx[k] * cb00 + dRy[k] * cb10
                d[i, j, 2] = dRx[k] * cb01 + dRy[k] * cb11
                for v in range(NV):
                    d[i, j, 3 + v] = -0.5 * rt * dmdot[v] * wts[v * n + k]
        block_cyclic_solve(jA, jB, jC, d, nr1, Dinv, E, T1, T2, Fb, G, gv)
        # capacitance I + Vᵀ Z, and Vᵀ z
        for a in range(NR):
            for b in range(NR):
                cap[a, b] = 1.0 if a == b else 0.0
            vr[a] = 0.0
        a2 = 2.0 * A
        for i in range(nt):
            ci = cs[i]
            si = cs[nt + i]
            for j in range(mz):
                k = i * mz + j
                for b in range(NR):
                    cap[0, b] += -a2 * ci * d[i, j, 1 + b]
                    cap[1, b] += -a2 * si * d[i, j, 1 + b]
                vr[0] += -a2 * ci * d[i, j, 0]
                vr[1] += -a2 * si * d[i, j, 0]
                for v in range(NV):
                    w = wts[v * n + k]
                    if w != 0.0:
                        for b in range(NR):
                            cap[2 + v, b] += w * d[i, j, 1 + b]
                        vr[2 + v] += w * d[i, j, 0]
        # y = cap⁻¹ (Vᵀ z)  (cap is overwritten)
        _solve_dense(cap, capi, vr, NR)
        # chamber pressures from the film's update: Vᵀδp = (δF_x, δF_y, δp̄_1..4)
        for v in range(NV):
            pm[v] = vr[NR + 2 + v]
        dfx = vr[NR]
        dfy = vr[NR + 1]
        updc = chamber_update(geo, pc, pm, cb00 * dfx + cb01 * dfy, cb10 * dfx + cb11 * dfy,
                              fw, resc, gch, 0.2 * pa)
        upd = updc
        for i in range(nt):
            for j in range(mz):
                k = i * mz + j
                dp = d[i, j, 0]
                for b in range(NR):
                    dp -= d[i, j, 1 + b] * vr[NR + b]
                pn = p[k] + dp
                if pn < 0.2 * pa:
                    pn = 0.2 * pa
                if abs(pn - p[k]) > upd:
                    upd = abs(pn - p[k])
                p[k] = pn
        if upd < tol * pa:
            break
    return upd / pa


@numba.njit(cache=True, nogil=True)
def _solve_dense(a, inv, v, m):
    """v[m:2m] = a⁻¹ v[:m] (Gauss–Jordan inverse of the solver module; a overwritten)."""
    inv_small(a, inv, m)
    for r in range(m):
        s = 0.0
        for q in range(m):
            s += inv[r, q] * v[q]
        v[m + r] = s


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
    # film history and predictor
    op = int(params[T_P])
    op1 = int(params[T_P1])
    ops = int(params[T_PSI])
    ops1 = int(params[T_PSI1])
    oh = int(params[W_HIST])
    for k in range(n):
        state[oh + k] = (4.0 * state[ops + k] - state[ops1 + k]) * inv2
        pn = state[op + k]
        pr = 2.0 * pn - state[op1 + k]
        state[op1 + k] = pn
        if pr > 0.5 * pn:
            state[op + k] = pr
    opc = int(params[T_PC])
    opc1 = int(params[T_PC1])
    ohc = int(params[W_HC])
    for v in range(NV):
        pn = state[opc + v]
        state[ohc + v] = (4.0 * pn - state[opc1 + v]) * inv2
        pr = 2.0 * pn - state[opc1 + v]
        state[opc1 + v] = pn
        if pr > 0.5 * pn:
            state[opc + v] = pr
    res = newton_film(state, params, blk, al, True, xk0, xk1, nit, 1e-12, al)
    state[ssc + ST_RES] = res
    if res > 1e-6:
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
    state[ssc + ST_XB] = xb
    state[ssc + ST_XB + 1] = yb
    # new film mass per cell, and the flows at the new time (for the mass balance)
    c = geo[G_C]
    A = geo[G_AREA]
    for i in range(nt):
        h = c - xb * cs[i] - yb * cs[nt + i]
        if h < H_MIN * c:
            h = H_MIN * c
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
    return newton_film(state, params, blk, 0.0, False, xb, yb, nit, tol, c0c)
