"""Health of the physics-grade plant's solver: the residual after a Newton update, and the
stop at contact or on a non-finite solution (docs/plant.md, "Failure").

Both run inside the kernel's sub-step (:mod:`rigd_drivers.reynolds.step`); nothing allocates.
"""

from __future__ import annotations

import numba

from rigd_drivers.reynolds.feed import F_MV, NFW, feed_flows
from rigd_drivers.reynolds.film import (
    G_AREA,
    G_C,
    G_CAP,
    G_MZ,
    G_NT,
    G_PA,
    G_RT,
    NV,
    film_force,
    film_gap,
    film_rates,
)
from rigd_drivers.reynolds.layout import (
    H_M,
    H_MZ,
    H_NT,
    ST_NAN,
    ST_SEQ,
    ST_STOP,
    ST_STOP_SEQ,
    STATUS_DIVERGED,
    T_P,
    T_P1,
    T_PC,
    T_PC1,
    T_Q,
    T_Q1,
    T_V,
    T_V1,
)


@numba.njit(cache=True, nogil=True)
def residual_measure(geo, cs, wts, p, cb00, cb01, cb10, cb11, xk0, xk1, omega, psup, af, rate,
                     outf, jA, jB, jC, dRx, dRy, pm, pc, histc, mdot, dmdot, fw, hist, c0, c0c):
    """The pressure change, as a fraction of p_a, that the BDF2 residual at the pressures ``p``
    (film) and ``pc`` (chambers) asks for over the step: max over the film cells of
    |R_k| / (c0 h_k A) and over the chambers of |r_c| / (cap c0c), / p_a (the journal at
    x_b = Cb F(p) + xk). NaN if anything is not finite. Leaves the film's own rates (without
    the injection) in ``rate``, the patch means in ``pm`` and the feed path's flows and
    partials (:func:`rigd_drivers.reynolds.feed.feed_flows`: the raw flows into the film ṁ_f
    in ``mdot``, for the mass balance) — what a chord step at these pressures starts from."""
    nt = int(geo[G_NT])
    mz = int(geo[G_MZ])
    fx, fy = film_force(geo, cs, p)
    xb = cb00 * fx + cb01 * fy + xk0
    yb = cb10 * fx + cb11 * fy + xk1
    film_rates(geo, cs, wts, p, xb, yb, omega, rate, outf, jA, jB, jC, dRx, dRy, pm, False)
    feed_flows(geo, pm, pc, xb, yb, psup, af, mdot, dmdot, fw)
    A = geo[G_AREA]
    c = geo[G_C]
    rt = geo[G_RT]
    n = nt * mz
    worst = 0.0
    for i in range(nt):
        h = film_gap(c, xb, yb, cs[i], cs[nt + i])
        s = c0 * h * A
        for j in range(mz):
            k = i * mz + j
            rk = rate[k]                # + the injection, as add_sources adds it
            for v in range(NV):
                w = wts[v * n + k]
                if w != 0.0:
                    rk += 0.5 * rt * mdot[v] * w
            e = abs(c0 * p[k] * h * A - hist[k] - rk) / s
            if not e <= worst:          # also NaN
                worst = e
    cap = geo[G_CAP]
    for v in range(NV):
        r = cap * (c0c * pc[v] - histc[v]) - fw[NFW * v + F_MV] + mdot[v]
        e = abs(r) / (cap * c0c)
        if not e <= worst:
            worst = e
    return worst / geo[G_PA]


@numba.njit(cache=True, nogil=True)
def stop_plant(state, params, ssc, bits):
    """Stop the plant: film, chambers and shaft back to the last time level (finite, ε < 1),
    the status bits latched for ``drv_status``; the kernel integrates no further sub-step."""
    n = int(params[H_NT]) * int(params[H_MZ])
    m = int(params[H_M])
    op = int(params[T_P])
    op1 = int(params[T_P1])
    for k in range(n):
        state[op + k] = state[op1 + k]
    opc = int(params[T_PC])
    opc1 = int(params[T_PC1])
    for v in range(NV):
        state[opc + v] = state[opc1 + v]
    oq = int(params[T_Q])
    ov = int(params[T_V])
    oq1 = int(params[T_Q1])
    ov1 = int(params[T_V1])
    for r in range(m):
        state[oq + r] = state[oq1 + r]
        state[ov + r] = state[ov1 + r]
    if bits == STATUS_DIVERGED:
        state[ssc + ST_NAN] += 1.0
    state[ssc + ST_STOP] = bits
    state[ssc + ST_STOP_SEQ] = state[ssc + ST_SEQ] + 1.0
