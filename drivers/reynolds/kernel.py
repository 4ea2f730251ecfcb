"""Compiled kernel of the physics-grade plant: ``plant_step(state, params, drive, frame_in)``.

One call advances one loop period T with the four valve drives held: the piezo valves
exactly (ZOH, as the ``sim`` plant), then ``n_sub`` BDF2 sub-steps of the coupled film +
shaft system (:func:`substep`), with the orifice areas interpolated linearly between the valve
positions at the start and the end of the period, then the sensors at the disc.

Array layouts: :mod:`rigd_drivers.reynolds.layout` (every offset is stored in the
``params`` header); the parameter block is active/staged/scratch with a sequence lock, as in
the ``sim`` plant.
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
from rigd_drivers.plant.amplifier import amplifier_output as _amplifier_output
from rigd_drivers.plant.noise import sensor_noise as _sensor_noise
from rigd_drivers.plant.seqlock import load_acquire, read_staged
from rigd_drivers.reynolds.film import NV
from rigd_drivers.reynolds.layout import (
    H_ACT,
    H_IMP_AXIS,
    H_IMP_DUR,
    H_IMP_PEAK,
    H_IMP_SEQ,
    H_M,
    H_NA,
    H_SCR,
    H_STAGE_SEQ,
    H_STG,
    O_PHID,
    O_SC,
    O_VGAM,
    O_VOFF,
    O_VPHI,
    SC_DT,
    SC_NOISE_E,
    SC_NOISE_Y,
    SC_NSUB,
    SC_OMEGA_RAD,
    SC_OMEGA_RPM,
    SC_PINJ,
    SC_PSUP,
    SC_PSUP_T,
    SC_SEED,
    SC_SENS,
    SC_SLEW,
    SC_T,
    SC_UNB,
    SC_UNB_PH,
    ST_APPLIED,
    ST_FH,
    ST_IMP_AXIS,
    ST_IMP_DUR,
    ST_IMP_ON,
    ST_IMP_PEAK,
    ST_IMP_SEEN,
    ST_IMP_T,
    ST_PHI,
    ST_PSUP,
    ST_RNG,
    ST_SEQ,
    ST_STOP,
    ST_T,
    T_AF0,
    T_FRAME,
    T_Q,
    T_SC,
    T_VPREV,
    T_XV,
    W_AF,
)
from rigd_drivers.reynolds.step import substep

TWO_PI = 2.0 * math.pi

@numba.njit(cache=True, nogil=True)
def _apply_staged(state, params):
    sc = int(params[T_SC])
    state[sc + ST_APPLIED] = read_staged(params, H_STAGE_SEQ, state[sc + ST_APPLIED],
                                         int(params[H_STG]), int(params[H_SCR]),
                                         int(params[H_ACT]), int(params[H_NA]))


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
    n0, n1, n2, n3, n4, n5 = _sensor_noise(seed, ctr, ne, ny)
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
    frame_in[IN_STATUS] = state[ssc + ST_STOP]
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
        omega_rpm, p_inj_bar, drv_seq and drv_status of the next sample (``STATUS_*`` bits of
        :mod:`rigd_drivers.reynolds.layout` once the plant stopped at contact or on a
        non-finite solution; it then stays frozen until :meth:`reset`).
    """
    _apply_staged(state, params)
    blk = int(params[H_ACT])
    sc = blk + int(params[O_SC])
    ssc = int(params[T_SC])
    T = params[sc + SC_T]
    # the supply follows its set point at the regulator's slew rate
    tgt = params[sc + SC_PSUP_T]
    cur = state[ssc + ST_PSUP]
    rate = params[sc + SC_SLEW]
    if rate <= 0.0 or cur <= 0.0 or abs(tgt - cur) <= rate:
        cur = tgt
    elif tgt > cur:
        cur += rate
    else:
        cur -= rate
    state[ssc + ST_PSUP] = cur
    params[sc + SC_PSUP] = cur
    imp_seq = load_acquire(params, H_IMP_SEQ)   # before the request's fields
    if imp_seq != state[ssc + ST_IMP_SEEN]:
        state[ssc + ST_IMP_SEEN] = imp_seq
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
        v = _amplifier_output(drive[i])    # [0, 10] V, NaN → 0 V
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
        if state[ssc + ST_STOP] == 0.0:     # stopped (contact, divergence): frozen
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


