"""Compiled kernel of the physics-grade plant: ``plant_step(state, params, drive, frame_in)``.

One call advances one loop period T with the four valve drives held: the piezo valves
exactly (ZOH, as the ``sim`` plant), then ``n_sub`` BDF2 sub-steps of the coupled film +
shaft system (:func:`substep`), with the orifice areas interpolated linearly between the valve
positions at the start and the end of the period, then the sensors at the disc.

Array layouts depend on the grid and the number of modes, so every offset is stored in the
``params`` header (slots ``H_*``, ``O_*``) by :mod:`rigd_drivers.sim_reynolds_params`; the
parameter block is active/staged/scratch with a sequence lock, as in the ``sim`` plant.
Nothing allocates per step (views only).
"""

from __future__ import annotations

import math

import numba

from rigd.frame import (
    IN_E_X,
    IN_E_Y,
    IN_F_X,
    IN_F_Y,
    IN_OMEGA,
    IN_P_INJ,
    IN_PHI,
    IN_SEQ,
    IN_STATUS,
    IN_YP1,
    N_IN,
)
from rigd_drivers.sim_noise import normal_pair as _normal_pair
from rigd_drivers.sim_reynolds_film import (
    G_AREA,
    G_C,
    G_N,
    H_MIN,
    NR,
    NV,
    block_cyclic_solve,
    film_force,
    film_rates,
)

TWO_PI = 2.0 * math.pi

# --- params header slots --------------------------------------------------------------------
H_STAGE_SEQ = 0
H_IMP_SEQ = 1
H_IMP_AXIS = 2
H_IMP_PEAK = 3
H_IMP_DUR = 4
H_ACT = 5            # active block start
H_STG = 6
H_SCR = 7
H_NA = 8             # block length
H_NT = 9
H_MZ = 10
H_M = 11             # modal coordinates (both planes)
_h = 12
# block-relative offsets (stored in the header)
O_GEO, O_CS, O_WTS, O_SINV, O_CR, O_PHIB, O_PHID, O_CB, O_VPHI, O_VGAM, O_VOFF, O_SC = \
    range(_h, _h + 12)
_h += 12
# state offsets (stored in the header)
(T_P, T_P1, T_PSI, T_PSI1, T_Q, T_V, T_Q1, T_V1, T_XV, T_VPREV, T_AF0, T_SC, T_FRAME,
 W_RATE, W_JA, W_JB, W_JC, W_DRX, W_DRY, W_D, W_DINV, W_E, W_T1, W_T2, W_FB, W_G, W_GV,
 W_MD, W_DMD, W_AF, W_OUT, W_CAP, W_CAPI, W_RK, W_HIST, W_VR, W_TMP) = range(_h, _h + 37)
N_HEADER = _h + 37

# scalars in the parameter block (relative to O_SC)
SC_OMEGA_RAD = 0
SC_OMEGA_RPM = 1
SC_PINJ = 2
SC_PSUP = 3          # absolute supply pressure, Pa
SC_DT = 4            # sub-step, s
SC_NSUB = 5
SC_NEWTON = 6        # Newton iterations per sub-step
SC_T = 7             # loop period, s
SC_NOISE_E = 8
SC_NOISE_Y = 9
SC_SEED = 10
SC_UNB = 11          # unbalance force amplitude at Ω, N
SC_UNB_PH = 12       # rad
SC_ALPHA = 13        # 3/(2 dt)
SC_SENS = 14         # sensor scale, µm per m (1e6)
N_SC = 16

# scalars in the state (relative to T_SC)
ST_T = 0
ST_PHI = 1
ST_SEQ = 2
ST_RNG = 3
ST_APPLIED = 4
ST_IMP_SEEN = 5
ST_IMP_ON = 6
ST_IMP_T = 7
ST_IMP_AXIS = 8
ST_IMP_PEAK = 9
ST_IMP_DUR = 10
ST_FH = 11           # 2: hammer force at the current sample, N
ST_MIN = 13          # cumulative orifice inflow mass × R_g T over the run, Pa m³
ST_MOUT = 14         # cumulative end outflow, Pa m³
ST_RES = 15          # last Newton residual (relative)
ST_FAIL = 16         # sub-steps whose last Newton update was not small
ST_XB = 17           # 2: bearing displacement, m
N_STSC = 20


@numba.njit(cache=True, nogil=True)
def _apply_staged(state, params):
    s1 = params[H_STAGE_SEQ]
    sc = int(params[T_SC])
    if s1 == state[sc + ST_APPLIED] or (int(s1) & 1) == 1:
        return
    na = int(params[H_NA])
    stg = int(params[H_STG])
    scr = int(params[H_SCR])
    act = int(params[H_ACT])
    for i in range(na):
        params[scr + i] = params[stg + i]
    if params[H_STAGE_SEQ] != s1:
        return
    for i in range(na):
        params[act + i] = params[scr + i]
    state[sc + ST_APPLIED] = s1


@numba.njit(cache=True, nogil=True)
def newton_film(state, params, blk, c0, dt_on, xk0, xk1, nit, tol):
    """Newton iterations for the film pressures (state's current p, in place).

    Residual R = c0·p h A − hist − rate(p, x_b(p)), x_b = Cb F(p) + xk (c0 = 3/(2dt), BDF2;
    c0 = 0 and Cb ignored with ``dt_on`` false: steady film at the fixed x_b = xk).
    Returns the last relative update ‖δp‖∞ / p_a.
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
    A = geo[G_AREA]
    c = geo[G_C]
    pa = geo[7]
    rt = geo[9]
    upd = 0.0
    for _ in range(nit):
        fx, fy = film_force(geo, cs, p)
        xb = cb00 * fx + cb01 * fy + xk0
        yb = cb10 * fx + cb11 * fy + xk1
        film_rates(geo, cs, wts, p, xb, yb, omega, psup, af, rate, outf, jA, jB, jC,
                   dRx, dRy, mdot, dmdot, True)
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
        upd = 0.0
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
    """v[m:2m] = a⁻¹ v[:m] (Gauss–Jordan; a overwritten, inv is work)."""
    for r in range(m):
        for s in range(m):
            inv[r, s] = 1.0 if r == s else 0.0
    for col in range(m):
        piv = col
        big = abs(a[col, col])
        for r in range(col + 1, m):
            if abs(a[r, col]) > big:
                big = abs(a[r, col])
                piv = r
        if piv != col:
            for s in range(m):
                t = a[col, s]
                a[col, s] = a[piv, s]
                a[piv, s] = t
                t = inv[col, s]
                inv[col, s] = inv[piv, s]
                inv[piv, s] = t
        dd = 1.0 / a[col, col]
        for s in range(m):
            a[col, s] *= dd
            inv[col, s] *= dd
        for r in range(m):
            if r != col:
                f = a[r, col]
                if f != 0.0:
                    for s in range(m):
                        a[r, s] -= f * a[col, s]
                        inv[r, s] -= f * inv[col, s]
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
    # a_q (in tmp), rk = α a_q + a_v + C_r a_q + Φ_dᵀ f_d
    inv2 = 1.0 / (2.0 * dt)
    for r in range(m):
        state[otmp + r] = (4.0 * state[oq + r] - state[oq1 + r]) * inv2
    for r in range(m):
        av = (4.0 * state[ov + r] - state[ov1 + r]) * inv2
        acc = al * state[otmp + r] + av
        for s in range(m):
            acc += params[ocr + r * m + s] * state[otmp + s]
        acc += params[ophid + r] * fdx + params[ophid + m + r] * fdy
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
    res = newton_film(state, params, blk, al, True, xk0, xk1, nit, 1e-12)
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
def _sense(state, params, frame_in):
    blk = int(params[H_ACT])
    m = int(params[H_M])
    sc = blk + int(params[O_SC])
    ssc = int(params[T_SC])
    ophid = blk + int(params[O_PHID])
    oq = int(params[T_Q])
    ex = 0.0
    ey = 0.0
    for r in range(m):
        ex += params[ophid + r] * state[oq + r]
        ey += params[ophid + m + r] * state[oq + r]
    scale = params[sc + SC_SENS]
    ex *= scale
    ey *= scale
    seed = params[sc + SC_SEED]
    ctr = state[ssc + ST_RNG]
    state[ssc + ST_RNG] = ctr + 6.0
    ne = params[sc + SC_NOISE_E]
    ny = params[sc + SC_NOISE_Y]
    n0 = 0.0
    n1 = 0.0
    n2 = 0.0
    n3 = 0.0
    n4 = 0.0
    n5 = 0.0
    if ne != 0.0:
        n0, n1 = _normal_pair(seed, ctr)
    if ny != 0.0:
        n2, n3 = _normal_pair(seed, ctr + 2.0)
        n4, n5 = _normal_pair(seed, ctr + 4.0)
    oxv = int(params[T_XV])
    ovo = blk + int(params[O_VOFF])
    frame_in[IN_E_X] = ex + ne * n0
    frame_in[IN_E_Y] = ey + ne * n1
    frame_in[IN_YP1] = state[oxv] + params[ovo] + ny * n2
    frame_in[IN_YP1 + 1] = state[oxv + 2] + params[ovo + 1] + ny * n3
    frame_in[IN_YP1 + 2] = state[oxv + 4] + params[ovo + 2] + ny * n4
    frame_in[IN_YP1 + 3] = state[oxv + 6] + params[ovo + 3] + ny * n5
    frame_in[IN_PHI] = state[ssc + ST_PHI]
    frame_in[IN_F_X] = state[ssc + ST_FH]
    frame_in[IN_F_Y] = state[ssc + ST_FH + 1]
    frame_in[IN_OMEGA] = params[sc + SC_OMEGA_RPM]
    frame_in[IN_P_INJ] = params[sc + SC_PINJ]
    frame_in[IN_SEQ] = state[ssc + ST_SEQ]
    frame_in[IN_STATUS] = 0.0
    of = int(params[T_FRAME])
    for i in range(N_IN):
        state[of + i] = frame_in[i]


@numba.njit(cache=True, nogil=True)
def area_fraction(y_p):
    """Orifice area fraction of a valve at position y_p (V): 0 V open (1) … 10 V closed (0)."""
    a = (10.0 - y_p) * 0.1
    if a < 0.0:
        return 0.0
    if a > 1.0:
        return 1.0
    return a


@numba.njit(cache=True, nogil=True)
def plant_step(state, params, drive, frame_in):
    """Integrate one loop period with ``drive`` (float64[4], V) held; sensors → ``frame_in``.

    Parameters
    ----------
    state, params : float64 arrays
        Plant state and parameters (layouts in the ``params`` header), mutated in place.
    drive : float64[4]
        Valve drive voltages v_1..v_4, V (clamped to [0, 10] V by the amplifiers).
    frame_in : float64[N_IN]
        Receives e_x, e_y (µm, at the disc), y_p1..4 (V), phi (rad), f_x, f_y (N),
        omega_rpm, p_inj_bar, drv_seq and drv_status of the next sample.
    """
    _apply_staged(state, params)
    blk = int(params[H_ACT])
    sc = blk + int(params[O_SC])
    ssc = int(params[T_SC])
    T = params[sc + SC_T]
    if params[H_IMP_SEQ] != state[ssc + ST_IMP_SEEN]:
        state[ssc + ST_IMP_SEEN] = params[H_IMP_SEQ]
        state[ssc + ST_IMP_ON] = 1.0
        state[ssc + ST_IMP_T] = 0.0
        state[ssc + ST_IMP_AXIS] = params[H_IMP_AXIS]
        state[ssc + ST_IMP_PEAK] = params[H_IMP_PEAK]
        state[ssc + ST_IMP_DUR] = params[H_IMP_DUR]
    # valves (exact ZOH), area fractions at the start (saved) and the end of the period
    oxv = int(params[T_XV])
    ovp = int(params[T_VPREV])
    oaf0 = int(params[T_AF0])
    ophi = blk + int(params[O_VPHI])
    ogam = blk + int(params[O_VGAM])
    ovo = blk + int(params[O_VOFF])
    for i in range(NV):
        v = drive[i]
        if v < 0.0:
            v = 0.0
        elif v > 10.0:
            v = 10.0
        if v != v:                              # NaN drive: amplifier holds 0 V
            v = 0.0
        state[ovp + i] = v
        p0 = state[oxv + 2 * i]
        p1 = state[oxv + 2 * i + 1]
        mo = ophi + 4 * i
        g = ogam + 2 * i
        state[oxv + 2 * i] = params[mo] * p0 + params[mo + 1] * p1 + params[g] * v
        state[oxv + 2 * i + 1] = params[mo + 2] * p0 + params[mo + 3] * p1 + params[g + 1] * v
    oaf = int(params[W_AF])
    nsub = int(params[sc + SC_NSUB])
    dt = params[sc + SC_DT]
    omega = params[sc + SC_OMEGA_RAD]
    fu = params[sc + SC_UNB]
    fph = params[sc + SC_UNB_PH]
    t0 = state[ssc + ST_T]
    fhx = 0.0
    fhy = 0.0
    for s in range(nsub):
        frac = (s + 1.0) / nsub
        for i in range(NV):
            y1 = state[oxv + 2 * i] + params[ovo + i]
            a1 = area_fraction(y1)
            state[oaf + i] = state[oaf0 + i] + (a1 - state[oaf0 + i]) * frac
        ts = t0 + (s + 1.0) * dt
        fx = 0.0
        fy = 0.0
        if state[ssc + ST_IMP_ON] != 0.0:
            ti = state[ssc + ST_IMP_T] + (s + 1.0) * dt
            dur = state[ssc + ST_IMP_DUR]
            if ti < dur:
                f = state[ssc + ST_IMP_PEAK] * math.sin(math.pi * ti / dur)
                if state[ssc + ST_IMP_AXIS] == 0.0:
                    fx = f
                else:
                    fy = f
        fhx = fx
        fhy = fy
        if fu != 0.0:
            a = omega * ts + fph
            fx += fu * math.cos(a)
            fy += fu * math.sin(a)
        substep(state, params, fx, fy)
    for i in range(NV):
        state[oaf0 + i] = state[oaf + i]
    if state[ssc + ST_IMP_ON] != 0.0:
        state[ssc + ST_IMP_T] += T
        if state[ssc + ST_IMP_T] >= state[ssc + ST_IMP_DUR]:
            state[ssc + ST_IMP_ON] = 0.0
    state[ssc + ST_FH] = fhx
    state[ssc + ST_FH + 1] = fhy
    state[ssc + ST_T] = t0 + T
    phi = state[ssc + ST_PHI] + omega * T
    if phi >= TWO_PI or phi < 0.0:
        phi = phi - TWO_PI * math.floor(phi / TWO_PI)
        if phi >= TWO_PI:
            phi = 0.0
    state[ssc + ST_PHI] = phi
    state[ssc + ST_SEQ] += 1.0
    _sense(state, params, frame_in)


@numba.njit(cache=True, nogil=True)
def plant_sense(state, params, frame_in):
    """Write the sensor frame of the current sample without advancing time."""
    _sense(state, params, frame_in)


@numba.njit(cache=True, nogil=True)
def run_batch(state, params, drives, frames):
    """Open-loop batch: ``plant_step`` for each row of ``drives`` (n, 4) into ``frames[i]``."""
    for i in range(drives.shape[0]):
        plant_step(state, params, drives[i], frames[i])


@numba.njit(cache=True, nogil=True)
def steady_film(state, params, xb, yb, nit, tol):
    """Steady film (no time term) at the fixed bearing displacement (xb, yb) m, in place on the
    state's pressures; orifice areas from the work slot ``W_AF``. Returns the last update."""
    blk = int(params[H_ACT])
    n = int(params[H_NT]) * int(params[H_MZ])
    oh = int(params[W_HIST])
    for k in range(n):
        state[oh + k] = 0.0
    return newton_film(state, params, blk, 0.0, False, xb, yb, nit, tol)
