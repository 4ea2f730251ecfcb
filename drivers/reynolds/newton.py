"""Newton's method for the film (and feed-chamber) pressures of one BDF2 sub-step or of the
steady film: the block-cyclic-tridiagonal film Jacobian
(:func:`rigd_drivers.reynolds.solver.block_cyclic_solve`) with the shaft (rank 2) and the four
injectors (rank 4) as a Sherman–Morrison–Woodbury update, the chamber pressures eliminated per
injector (:mod:`rigd_drivers.reynolds.feed`), convergence judged on the residual after the
update (:mod:`rigd_drivers.reynolds.health`). Nothing allocates (views into the kernel's arrays).
"""

from __future__ import annotations

import math

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
    NR,
    NV,
    film_force,
    film_gap,
    film_rates,
)
from rigd_drivers.reynolds.health import residual_measure
from rigd_drivers.reynolds.layout import (
    H_MZ,
    H_NT,
    O_CB,
    O_CS,
    O_GEO,
    O_SC,
    O_WTS,
    SC_OMEGA_RAD,
    SC_PSUP,
    ST_NEWTON_IT,
    ST_PFLOOR,
    T_P,
    T_PC,
    T_SC,
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
    W_T1,
    W_T2,
    W_VR,
)
from rigd_drivers.reynolds.solver import block_cyclic_resolve, block_cyclic_solve, inv_small


@numba.njit(cache=True, nogil=True)
def newton_film(state, params, blk, c0, dt_on, xk0, xk1, nit, nmax, tol, c0c):
    """Newton iterations for the film pressures (state's current p, in place).

    Residual R = c0·p h A − hist − rate(p, x_b(p)), x_b = Cb F(p) + xk (c0 = 3/(2dt), BDF2;
    c0 = 0 and Cb ignored with ``dt_on`` false: steady film at the fixed x_b = xk).
    The chamber pressures of the feed path are unknowns too (eliminated per injector,
    :mod:`rigd_drivers.reynolds.feed`; their time factor ``c0c`` — ``c0`` but for
    :func:`steady_film`'s frozen chambers — and history in ``W_HC``).

    Time step (``dt_on``): at least ``nit`` and at most ``nmax`` iterations; after each update
    from the ``nit``-th on, the residual at the updated pressures is evaluated
    (:func:`rigd_drivers.reynolds.health.residual_measure`) and the iterations stop once the
    pressure change it asks for over the step, as a fraction of p_a, is below ``tol``.
    Returns that measure (NaN if the solution is not finite). Steady film: at most ``nit``
    iterations, stopping when the update is below ``tol`` p_a; returns the last update
    max(‖δp‖∞, ‖δp_c‖∞) / p_a. In a time step, updates clipped at the pressure floor
    (0.2 p_a) are counted in ``ST_PFLOOR`` (once per call), the iterations in
    ``ST_NEWTON_IT``.
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
    ssc = int(params[T_SC])
    upd = 0.0
    clipped = False
    it = 0
    chord = False
    while True:
        if dt_on and it >= nit:
            upd = residual_measure(geo, cs, wts, p, cb00, cb01, cb10, cb11, xk0, xk1, omega,
                                   psup, af, rate, outf, jA, jB, jC, dRx, dRy, pm, pc, histc,
                                   mdot, dmdot, fw, hist, c0, c0c)
            if upd < tol or it >= nmax or math.isnan(upd):
                break
            # the first iteration past nit reuses the last Jacobian's factors (a chord step:
            # same residual, same test after it); any further one is a full Newton step. The
            # chord step starts from the film rates and feed flows just evaluated at these
            # pressures (``rate`` holds the film's own, without the sources)
            chord = it == nit
        elif not dt_on and it >= nit:
            break
        else:
            chord = False
        it += 1
        fx, fy = film_force(geo, cs, p)
        xb = cb00 * fx + cb01 * fy + xk0
        yb = cb10 * fx + cb11 * fy + xk1
        if not chord:
            film_rates(geo, cs, wts, p, xb, yb, omega, rate, outf, jA, jB, jC, dRx, dRy, pm,
                       True)
            feed_flows(geo, pm, pc, xb, yb, psup, af, mdot, dmdot, fw)
        chamber_eliminate(geo, c0c, pc, histc, mdot, dmdot, fw, resc, gch)
        add_sources(geo, wts, mdot, fw, rate, dRx, dRy, not chord)
        if chord:
            _chord_solve(nt, mz, n, c, A, c0, xb, yb, cs, wts, p, hist, rate, d, jA, jC, Dinv,
                         E, T2, gv, capi, vr)
        else:
            _newton_solve(nt, mz, n, c, A, c0, xb, yb, cs, wts, p, hist, rate, d, jA, jB, jC,
                          dRx, dRy, Dinv, E, T1, T2, Fb, G, gv, cap, capi, vr, cb00, cb01,
                          cb10, cb11, rt, dmdot, nr1)
        # chamber pressures from the film's update: Vᵀδp = (δF_x, δF_y, δp̄_1..4)
        for v in range(NV):
            pm[v] = vr[NR + 2 + v]
        dfx = vr[NR]
        dfy = vr[NR + 1]
        updc = chamber_update(geo, pc, pm, cb00 * dfx + cb01 * dfy, cb10 * dfx + cb11 * dfy,
                              fw, resc, gch, 0.2 * pa)
        upd = updc
        for v in range(NV):
            if pc[v] <= 0.2 * pa:
                clipped = True
        for i in range(nt):
            for j in range(mz):
                k = i * mz + j
                dp = d[i, j, 0]
                for b in range(NR):
                    dp -= d[i, j, 1 + b] * vr[NR + b]
                pn = p[k] + dp
                if pn < 0.2 * pa:
                    pn = 0.2 * pa
                    clipped = True
                if abs(pn - p[k]) > upd:
                    upd = abs(pn - p[k])
                p[k] = pn
        upd /= pa
        if not dt_on and upd < tol:
            break
    if dt_on:                           # the kernel's sub-steps (not the steady solves)
        state[ssc + ST_NEWTON_IT] += it
        if clipped:
            state[ssc + ST_PFLOOR] += 1.0
    return upd


@numba.njit(cache=True, nogil=True)
def _newton_solve(nt, mz, n, c, A, c0, xb, yb, cs, wts, p, hist, rate, d, jA, jB, jC, dRx, dRy,
                  Dinv, E, T1, T2, Fb, G, gv, cap, capi, vr, cb00, cb01, cb10, cb11, rt, dmdot,
                  nr1):
    """A full Newton step's linear algebra: the Jacobian completed with the time term, the
    block solve of the residual and the low-rank columns Z, the capacitance I + VᵀZ (its
    inverse kept in ``capi``) and y = cap⁻¹ Vᵀz in ``vr[NR:]``."""
    for i in range(nt):
        ci = cs[i]
        si = cs[nt + i]
        h = film_gap(c, xb, yb, ci, si)
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
    for b in range(NR):
        _vt_column(nt, mz, n, A, cs, wts, d, 1 + b, cap[:, b])
    _vt_column(nt, mz, n, A, cs, wts, d, 0, vr)
    # y = cap⁻¹ (Vᵀ z)  (cap is overwritten)
    inv_small(cap, capi, NR)
    _matvec(capi, vr, NR)


@numba.njit(cache=True, nogil=True)
def _chord_solve(nt, mz, n, c, A, c0, xb, yb, cs, wts, p, hist, rate, d, jA, jC, Dinv, E, Ginv,
                 gv, capi, vr):
    """A chord step's linear algebra: the new residual solved with the factors, the low-rank
    columns Z and the capacitance inverse ``capi`` of the last full Newton step (all still in
    their work arrays); y = cap⁻¹ Vᵀz in ``vr[NR:]``. O(n mz²) instead of O(n mz³)."""
    for i in range(nt):
        h = film_gap(c, xb, yb, cs[i], cs[nt + i])
        for j in range(mz):
            k = i * mz + j
            d[i, j, 0] = hist[k] + rate[k] - c0 * p[k] * h * A
    block_cyclic_resolve(jA, jC, d, Dinv, E, Ginv, gv)
    for a in range(NR):
        vr[a] = 0.0
    _vt_column(nt, mz, n, A, cs, wts, d, 0, vr)
    _matvec(capi, vr, NR)


@numba.njit(cache=True, nogil=True)
def _vt_column(nt, mz, n, A, cs, wts, d, col, out):
    """out[:NR] += Vᵀ d[:, :, col]: the low-rank rows V of the Woodbury update (film force
    x, y — the area 2A cos θ, sin θ with its sign — and the four feed-patch means) applied
    to one column of the block solve, accumulated cell by cell in k order."""
    a2 = 2.0 * A
    for i in range(nt):
        ci = cs[i]
        si = cs[nt + i]
        for j in range(mz):
            k = i * mz + j
            out[0] += -a2 * ci * d[i, j, col]
            out[1] += -a2 * si * d[i, j, col]
            for v in range(NV):
                w = wts[v * n + k]
                if w != 0.0:
                    out[2 + v] += w * d[i, j, col]


@numba.njit(cache=True, nogil=True)
def _matvec(inv, v, m):
    """v[m:2m] = inv · v[:m] (m × m)."""
    for r in range(m):
        s = 0.0
        for q in range(m):
            s += inv[r, q] * v[q]
        v[m + r] = s
