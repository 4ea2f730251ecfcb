"""Compiled kernel of the simulated plant: ``plant_step(state, params, drive, frame_in)``.

One call integrates one loop period T with the four drive voltages held (ZOH) and writes the
sensors of the next sample into ``frame_in`` (layout :mod:`rigd.frame`). Nothing allocates.

Array layouts (float64, offsets below):

* ``params`` = header ``[0, ACT)`` + active block ``[ACT, ACT+NA)`` + staged block
  ``[STG, STG+NA)`` + scratch block. The Python side writes a new operating point into the
  staged block under a sequence lock (``H_STAGE_SEQ`` odd while writing); the kernel copies it
  to scratch, re-checks the sequence and only then to the active block, at the start of a step:
  no torn parameter sets (ordered loads and stores: :mod:`rigd_drivers.plant.seqlock`).
  Impact requests go through the header the same way (``H_IMP_SEQ``).
* ``state``: bearing states, valve states, hysteresis and creep states, the delay line,
  time, encoder angle, counters and the last sensor frame.

Integration: valves exactly (ZOH on the drive); the bearing (Eq. 4/5, augmented with the
optional extra mode) exactly for a first-order-hold input w = [u_x, u_y, f_x, f_y] (u linear
between samples, as the continuous valve motion is), computed from exp of the augmented
matrix when the operating point changes; with cubic stiffness on, the period is split into
``substeps`` and the film force enters as an FOH input by a predictor–corrector (Heun) step.
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

NX = 6          # bearing states: e_x, e_y, de_x, de_y, q, dq (q: extra mode)
NW = 4          # FOH inputs: u_x, u_y (V), f_x, f_y (N)
DMAX = 64       # delay line length (samples)
TWO_PI = 2.0 * math.pi

_n = 0


def _take(size: int) -> int:
    global _n
    off = _n
    _n += size
    return off


# --- active parameter block (offsets relative to the block) -------------------------------
A_PHI = _take(NX * NX)        # full-period bearing transition
A_G0 = _take(NX * NW)         # FOH: x+ = Φx + G0 w_k + G1 w_{k+1}
A_G1 = _take(NX * NW)
A_SPHI = _take(NX * NX)       # same for one sub-step T/substeps
A_SG0 = _take(NX * NW)
A_SG1 = _take(NX * NW)
A_C = _take(2 * NX)           # sensors e = C x
A_VPHI = _take(16)            # 4 valves × 2×2 (ZOH transition)
A_VGAM = _take(8)             # 4 valves × 2 (ZOH input, includes the valve gain)
A_VOFF = _take(4)             # valve position offsets, V
A_NSUB = _take(1)
A_K3 = _take(1)               # cubic film stiffness, N/µm³ (0 = off)
A_DELAY = _take(1)            # samples (0 = off)
A_HYST_ON = _take(1)
A_HYST_ALPHA = _take(1)
A_HYST_B = _take(1)           # β = γ
A_HYST_HMAX = _take(1)
A_CREEP_ON = _take(1)
A_CREEP_A = _take(2)          # exp(−T/τ_j)
A_CREEP_F = _take(2)          # fractions
A_RO_ON = _take(1)
A_RO = _take(8)               # x: a1, θ1, a2, θ2; y: a1, θ1, a2, θ2 (µm, rad)
A_UNB = _take(2)              # unbalance force at this Ω (N), phase (rad)
A_NOISE_E = _take(1)
A_NOISE_Y = _take(1)
A_SEED = _take(1)
A_OMEGA_RAD = _take(1)
A_OMEGA_RPM = _take(1)
A_PINJ = _take(1)
A_T = _take(1)                # loop period, s
A_NX = _take(1)               # bearing states in use: 4, or 6 with the extra mode
NA = _n

# --- params header and blocks --------------------------------------------------------------
H_STAGE_SEQ = 0               # seqlock of the staged block (odd while writing)
H_IMP_SEQ = 1                 # impact request counter (incremented last)
H_IMP_AXIS = 2                # 0 = x, 1 = y
H_IMP_PEAK = 3                # N
H_IMP_DUR = 4                 # s
ACT = 8
STG = ACT + NA
SCR = STG + NA
N_PARAMS = SCR + NA

# --- state ----------------------------------------------------------------------------------
_n = 0
S_X = _take(NX)
S_XV = _take(8)               # valve i: position (before offset), velocity
S_CREEP = _take(8)            # valve i: two creep states
S_HYST = _take(4)
S_VPREV = _take(4)
S_W = _take(NW)               # FOH input at the current sample
S_UBUF = _take(2 * DMAX)      # delay line of u (x at even, y at odd slots)
S_UPOS = _take(1)
S_T = _take(1)
S_PHI = _take(1)
S_SEQ = _take(1)
S_RNG = _take(1)              # noise draw counter
S_APPLIED = _take(1)          # last applied staged sequence
S_IMP_SEEN = _take(1)
S_IMP_ON = _take(1)
S_IMP_T = _take(1)
S_IMP_AXIS = _take(1)
S_IMP_PEAK = _take(1)
S_IMP_DUR = _take(1)
S_FH = _take(2)               # hammer force at the current sample, N
S_FRAME = _take(N_IN)         # last sensor frame (what read() returns)
S_XN = _take(NX)              # scratch: next bearing state
S_XP = _take(NX)              # scratch: predictor state
N_STATE = _n

@numba.njit(cache=True, nogil=True)
def _apply_staged(state, params):
    state[S_APPLIED] = read_staged(params, H_STAGE_SEQ, state[S_APPLIED], STG, SCR, ACT, NA)


@numba.njit(cache=True, nogil=True)
def _hyst(h, dv, alpha, b, hmax):
    """Exact Bouc–Wen (n = 1, β = γ = b) update of h for a monotone drive change dv."""
    if dv == 0.0:
        return h
    sg = 1.0 if dv > 0.0 else -1.0
    a = abs(dv)
    hs = sg * h                         # h measured along the direction of motion
    if hs < 0.0:                        # linear part until h crosses zero
        need = -hs / alpha
        if a <= need:
            return h + sg * alpha * a
        a -= need
        hs = 0.0
    hs = hmax + (hs - hmax) * math.exp(-2.0 * b * a)
    return sg * hs


@numba.njit(cache=True, nogil=True)
def _foh(state, params, src, dst, off_phi, off_g0, off_g1, wa0, wa1, wa2, wa3,
         wb0, wb1, wb2, wb3):
    """state[dst:dst+NX] = Φ·state[src:] + G0·wa + G1·wb (one FOH interval)."""
    nx = int(params[ACT + A_NX])
    for i in range(nx):
        acc = 0.0
        r = ACT + off_phi + i * NX
        for j in range(nx):
            acc += params[r + j] * state[src + j]
        g0 = ACT + off_g0 + i * NW
        g1 = ACT + off_g1 + i * NW
        acc += (params[g0] * wa0 + params[g0 + 1] * wa1 + params[g0 + 2] * wa2
                + params[g0 + 3] * wa3)
        acc += (params[g1] * wb0 + params[g1 + 1] * wb1 + params[g1 + 2] * wb2
                + params[g1 + 3] * wb3)
        state[dst + i] = acc


@numba.njit(cache=True, nogil=True)
def _sense(state, params, frame_in):
    """Write the sensor frame of the current sample into frame_in and state[S_FRAME]."""
    P = ACT
    ex = 0.0
    ey = 0.0
    nx = int(params[P + A_NX])
    for j in range(nx):
        ex += params[P + A_C + j] * state[S_X + j]
        ey += params[P + A_C + NX + j] * state[S_X + j]
    if params[P + A_RO_ON] != 0.0:
        phi = state[S_PHI]
        ex += (params[P + A_RO] * math.cos(phi + params[P + A_RO + 1])
               + params[P + A_RO + 2] * math.cos(2.0 * phi + params[P + A_RO + 3]))
        ey += (params[P + A_RO + 4] * math.cos(phi + params[P + A_RO + 5])
               + params[P + A_RO + 6] * math.cos(2.0 * phi + params[P + A_RO + 7]))
    seed = params[P + A_SEED]
    ctr = state[S_RNG]
    state[S_RNG] = ctr + 6.0
    ne = params[P + A_NOISE_E]
    ny = params[P + A_NOISE_Y]
    n0, n1, n2, n3, n4, n5 = _sensor_noise(seed, ctr, ne, ny)
    frame_in[IN_E_X] = ex + ne * n0
    frame_in[IN_E_Y] = ey + ne * n1
    frame_in[IN_YP1] = state[S_XV] + params[P + A_VOFF] + ny * n2
    frame_in[IN_YP1 + 1] = state[S_XV + 2] + params[P + A_VOFF + 1] + ny * n3
    frame_in[IN_YP1 + 2] = state[S_XV + 4] + params[P + A_VOFF + 2] + ny * n4
    frame_in[IN_YP1 + 3] = state[S_XV + 6] + params[P + A_VOFF + 3] + ny * n5
    frame_in[IN_PHI] = state[S_PHI]
    frame_in[IN_F_X] = state[S_FH]
    frame_in[IN_F_Y] = state[S_FH + 1]
    frame_in[IN_OMEGA] = params[P + A_OMEGA_RPM]
    frame_in[IN_P_INJ] = params[P + A_PINJ]
    frame_in[IN_SEQ] = state[S_SEQ]
    frame_in[IN_STATUS] = 0.0
    for i in range(N_IN):
        state[S_FRAME + i] = frame_in[i]


@numba.njit(cache=True, nogil=True)
def _film_force(state, base, k3):
    """Cubic film force −k3·|p|²·p (N) at the bearing state starting at state[base]."""
    ex = state[base]
    ey = state[base + 1]
    r2 = ex * ex + ey * ey
    return -k3 * r2 * ex, -k3 * r2 * ey


@numba.njit(cache=True, nogil=True)
def plant_step(state, params, drive, frame_in):
    """Integrate one loop period with ``drive`` (float64[4], V) held; sensors → ``frame_in``.

    Parameters
    ----------
    state, params : float64 arrays
        Plant state and parameters (layouts in this module), mutated in place.
    drive : float64[4]
        Valve drive voltages v_1..v_4, V (the amplifiers clamp to [0, 10] V).
    frame_in : float64[N_IN]
        Receives e_x, e_y (µm), y_p1..4 (V), phi (rad), f_x, f_y (N), omega_rpm, p_inj_bar,
        drv_seq (incremented every step) and drv_status (0) of the next sample.
    """
    _apply_staged(state, params)
    P = ACT
    T = params[P + A_T]
    # --- impact request (half-sine hammer pulse) ------------------------------------------
    imp_seq = load_acquire(params, H_IMP_SEQ)   # before the request's fields
    if imp_seq != state[S_IMP_SEEN]:
        state[S_IMP_SEEN] = imp_seq
        state[S_IMP_ON] = 1.0
        state[S_IMP_T] = 0.0
        state[S_IMP_AXIS] = params[H_IMP_AXIS]
        state[S_IMP_PEAK] = params[H_IMP_PEAK]
        state[S_IMP_DUR] = params[H_IMP_DUR]
    # --- valves: hysteresis, creep, second-order dynamics (exact ZOH) ---------------------
    hyst_on = params[P + A_HYST_ON] != 0.0
    creep_on = params[P + A_CREEP_ON] != 0.0
    for i in range(4):
        v = _amplifier_output(drive[i])    # [0, 10] V, NaN → 0 V
        vprev = state[S_VPREV + i]
        state[S_VPREV + i] = v                 # the amplifier output (clamped)
        if hyst_on:
            h = _hyst(state[S_HYST + i], v - vprev, params[P + A_HYST_ALPHA],
                      params[P + A_HYST_B], params[P + A_HYST_HMAX])
            state[S_HYST + i] = h
            v = v - h
        if creep_on:
            c0 = state[S_CREEP + 2 * i]
            c1 = state[S_CREEP + 2 * i + 1]
            a0 = params[P + A_CREEP_A]
            a1 = params[P + A_CREEP_A + 1]
            state[S_CREEP + 2 * i] = a0 * c0 + (1.0 - a0) * params[P + A_CREEP_F] * v
            state[S_CREEP + 2 * i + 1] = a1 * c1 + (1.0 - a1) * params[P + A_CREEP_F + 1] * v
            v = v + c0 + c1
        p0 = state[S_XV + 2 * i]
        p1 = state[S_XV + 2 * i + 1]
        m = P + A_VPHI + 4 * i
        g = P + A_VGAM + 2 * i
        state[S_XV + 2 * i] = params[m] * p0 + params[m + 1] * p1 + params[g] * v
        state[S_XV + 2 * i + 1] = params[m + 2] * p0 + params[m + 3] * p1 + params[g + 1] * v
    # lumped valve positions (Eq. 1) from the true positions
    ux = (state[S_XV + 2] + params[P + A_VOFF + 1]) - (state[S_XV + 6] + params[P + A_VOFF + 3])
    uy = (state[S_XV] + params[P + A_VOFF]) - (state[S_XV + 4] + params[P + A_VOFF + 2])
    # --- delay line valve → film force -----------------------------------------------------
    pos = int(state[S_UPOS])
    pos = pos + 1 if pos + 1 < DMAX else 0
    state[S_UPOS] = pos
    state[S_UBUF + 2 * pos] = ux
    state[S_UBUF + 2 * pos + 1] = uy
    d = int(params[P + A_DELAY])
    if d > 0:
        q = pos - d
        if q < 0:
            q += DMAX
        ux = state[S_UBUF + 2 * q]
        uy = state[S_UBUF + 2 * q + 1]
    # --- time, encoder angle, forces at the next sample ------------------------------------
    state[S_T] += T
    phi = state[S_PHI] + params[P + A_OMEGA_RAD] * T
    if phi >= TWO_PI or phi < 0.0:
        phi = phi - TWO_PI * math.floor(phi / TWO_PI)
        if phi >= TWO_PI:
            phi = 0.0
    state[S_PHI] = phi
    fhx = 0.0
    fhy = 0.0
    if state[S_IMP_ON] != 0.0:
        ti = state[S_IMP_T] + T
        state[S_IMP_T] = ti
        dur = state[S_IMP_DUR]
        if ti < dur:
            f = state[S_IMP_PEAK] * math.sin(math.pi * ti / dur)
            if state[S_IMP_AXIS] == 0.0:
                fhx = f
            else:
                fhy = f
        else:
            state[S_IMP_ON] = 0.0
    state[S_FH] = fhx
    state[S_FH + 1] = fhy
    fx = fhx
    fy = fhy
    if params[P + A_RO_ON] != 0.0:
        fu = params[P + A_UNB]
        if fu != 0.0:
            a = phi + params[P + A_UNB + 1]
            fx += fu * math.cos(a)
            fy += fu * math.sin(a)
    # --- bearing: FOH over the period (sub-stepped with the cubic film force) -------------
    wa0 = state[S_W]
    wa1 = state[S_W + 1]
    wa2 = state[S_W + 2]
    wa3 = state[S_W + 3]
    k3 = params[P + A_K3]
    if k3 == 0.0:
        _foh(state, params, S_X, S_XN, A_PHI, A_G0, A_G1, wa0, wa1, wa2, wa3, ux, uy, fx, fy)
        for i in range(NX):
            state[S_X + i] = state[S_XN + i]
    else:
        n = int(params[P + A_NSUB])
        inv = 1.0 / n
        for j in range(n):
            sa = j * inv
            sb = (j + 1) * inv
            a0 = wa0 + (ux - wa0) * sa
            a1 = wa1 + (uy - wa1) * sa
            a2 = wa2 + (fx - wa2) * sa
            a3 = wa3 + (fy - wa3) * sa
            b0 = wa0 + (ux - wa0) * sb
            b1 = wa1 + (uy - wa1) * sb
            b2 = wa2 + (fx - wa2) * sb
            b3 = wa3 + (fy - wa3) * sb
            nax, nay = _film_force(state, S_X, k3)
            _foh(state, params, S_X, S_XP, A_SPHI, A_SG0, A_SG1,
                 a0, a1, a2 + nax, a3 + nay, b0, b1, b2 + nax, b3 + nay)
            nbx, nby = _film_force(state, S_XP, k3)
            _foh(state, params, S_X, S_XN, A_SPHI, A_SG0, A_SG1,
                 a0, a1, a2 + nax, a3 + nay, b0, b1, b2 + nbx, b3 + nby)
            for i in range(NX):
                state[S_X + i] = state[S_XN + i]
    state[S_W] = ux
    state[S_W + 1] = uy
    state[S_W + 2] = fx
    state[S_W + 3] = fy
    state[S_SEQ] += 1.0
    _sense(state, params, frame_in)


@numba.njit(cache=True, nogil=True)
def plant_sense(state, params, frame_in):
    """Write the sensor frame of the current sample without advancing time (no noise draw
    is skipped: the noise counter advances as in a step)."""
    _sense(state, params, frame_in)


@numba.njit(cache=True, nogil=True)
def run_batch(state, params, drives, frames):
    """Open-loop batch: ``plant_step`` for each row of ``drives`` (n, 4) into ``frames[i]``."""
    for i in range(drives.shape[0]):
        plant_step(state, params, drives[i], frames[i])
