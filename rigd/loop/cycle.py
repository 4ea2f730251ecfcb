"""The cycle as numba kernels on preallocated float64 arrays (no allocation, no Python).

One cycle (docs/ARCHITECTURE.md, "The cycle")::

    calibrate the input frame -> supervisor checks (latch a fault -> safe state)
    -> K∞(z): k = C x + D e, x+ = A x + B e with e = -(p - p_eq)   (hot standby)
    -> r = ramp * k + excitation -> r_p = map(r)  (Eq. 1) -> 4 x PD -> clamp -> drive
    -> one record frame into the ring buffer

Names from the paper: r = [r_x, r_y] lumped valve references (V), r_p,i per-valve references
(V), y_p,i measured valve positions (V), u = [u_x, u_y] lumped valve positions (V),
p = [e_x, e_y] shaft displacement (µm), K∞ the outer H∞ controller (Sec. 5, Eq. 11).

Array layouts are in :mod:`rigd.loop.layout`. Every kernel is ``cache=True`` so a process pays
the compile once per machine.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from rigd import frame as F
from rigd.loop import faults as FC
from rigd.loop.layout import (
    FLOG_N,
    H_BIN_NS,
    H_COUNT,
    H_MAX,
    H_NB,
    H_OVER,
    N_REQ_SRC,
    P_CAL_G,
    P_CAL_O,
    P_CX,
    P_CY,
    P_DA,
    P_DB,
    P_E_MAX,
    P_E_MIN,
    P_ENC_N,
    P_ENC_OMEGA,
    P_FS,
    P_GAP_MAX,
    P_GRACE_N,
    P_KA,
    P_KB,
    P_KC,
    P_KD,
    P_KD_MAT,
    P_KFF,
    P_KN,
    P_KP,
    P_LOST_DECAY,
    P_PEQ_ALPHA,
    P_PERIOD_NS,
    P_R0,
    P_RAMP_STEP,
    P_RING_N,
    P_STALE_N,
    P_STALL_NS,
    P_STORM_NS,
    P_SUP_ON,
    P_VERR_N,
    P_VERR_V,
    P_VMAX,
    P_VMIN,
    P_Y_MAX,
    P_Y_MIN,
    S_DF,
    S_DROPPED,
    S_EPREV,
    S_FAULT,
    S_FAULT_DETAIL,
    S_FAULT_SEQ,
    S_FLOG,
    S_FREQ,
    S_K_OUT_X,
    S_K_OUT_Y,
    S_K_TARGET,
    S_LAST_DRVSEQ,
    S_LAST_PHI,
    S_LISTED,
    S_LOST_NS,
    S_NFAULT,
    S_PEQ_INIT,
    S_PEQ_X,
    S_PEQ_Y,
    S_PHI_CNT,
    S_RAMP,
    S_RD,
    S_RP_PREV,
    S_SAFE_GEN,
    S_SAFE_SEEN,
    S_SEQ,
    S_SLOW_BAD,
    S_SLOW_OMEGA,
    S_SLOW_PINJ,
    S_STALE_CNT,
    S_STALL_SEEN,
    S_VERR_CNT,
    S_W,
    S_X,
    S_XN,
    S_Y,
)
from rigd.loop.safeword import (
    W_ACK_CODE,
    W_ACK_FAULT_SEQ,
    W_ACK_N,
    W_ACK_SEQ,
    W_CYCLE_NS,
    W_FAULT,
    W_FAULT_SEQ,
    W_LOOP_GAP_NS,
    W_REQ,
    W_SEQ,
    W_STALL_FROM,
    W_STALL_REQ,
)

N_IN = F.N_IN
IN_E_X, IN_E_Y, IN_PHI = F.IN_E_X, F.IN_E_Y, F.IN_PHI
IN_YP1 = F.IN_YP1
IN_OMEGA, IN_P_INJ, IN_SEQ, IN_STATUS = F.IN_OMEGA, F.IN_P_INJ, F.IN_SEQ, F.IN_STATUS
IN_F_X, IN_F_Y = F.IN_F_X, F.IN_F_Y
_R = F.REC
R_SEQ, R_T, R_EX, R_EY = _R["seq"], _R["t"], _R["e_x"], _R["e_y"]
R_YP1, R_PHI, R_FX, R_FY = _R["y_p1"], _R["phi"], _R["f_x"], _R["f_y"]
R_OMEGA, R_PINJ, R_RX, R_RY = _R["omega_rpm"], _R["p_inj_bar"], _R["r_x"], _R["r_y"]
R_KX, R_KY, R_XX, R_XY = _R["k_x"], _R["k_y"], _R["x_x"], _R["x_y"]
R_RP1, R_UX, R_UY, R_V1 = _R["r_p1"], _R["u_x"], _R["u_y"], _R["v_1"]
R_KON, R_FAULT = _R["k_on"], _R["fault"]


# --- small blocks (each usable and testable on its own) ----------------------------------
@njit(cache=True, inline="always")
def eq1(r0, rx, ry):
    """Pairwise mapping r -> r_p of Eq. 1: (r0 + r_y, r0 + r_x, r0 - r_y, r0 - r_x), V."""
    return r0 + ry, r0 + rx, r0 - ry, r0 - rx


@njit(cache=True, inline="always")
def clamp(v, lo, hi):
    """Clamp ``v`` to [lo, hi]; a non-finite ``v`` becomes ``lo`` (never an unsafe command)."""
    if v > hi:
        return hi
    if v >= lo:
        return v
    return lo


@njit(cache=True)
def ss_step(prm, st, e0, e1):
    """One K∞(z) update: returns k = C x + D e, then x <- A x + B e (``prm``/``st`` layout).

    The order n is ``prm[P_KN]`` (0: zero output). Matches python-control's discrete
    ``forced_response`` of ``ss(A, B, C, D, dt)`` sample by sample.
    """
    n = int(prm[P_KN])
    k0 = prm[P_KD_MAT] * e0 + prm[P_KD_MAT + 1] * e1
    k1 = prm[P_KD_MAT + 2] * e0 + prm[P_KD_MAT + 3] * e1
    for j in range(n):
        xj = st[S_X + j]
        k0 += prm[P_KC + j] * xj
        k1 += prm[P_KC + n + j] * xj
    for i in range(n):
        acc = prm[P_KB + 2 * i] * e0 + prm[P_KB + 2 * i + 1] * e1
        row = P_KA + i * n
        for j in range(n):
            acc += prm[row + j] * st[S_X + j]
        st[S_XN + i] = acc
    for i in range(n):
        st[S_X + i] = st[S_XN + i]
    return k0, k1


@njit(cache=True, inline="always")
def pd_step(prm, st, i, ref, meas):
    """PD loop of valve ``i`` (0..3): drive voltage for reference ``ref`` and position ``meas``.

    v = kff·r_p + kp·e + kd·d_f, e = r_p - y_p, with the derivative filtered by a first-order
    low-pass of time constant tf (backward Euler: d_f+ = a d_f + b (e - e_prev),
    a = tf/(tf+T), b = 1/(tf+T)); the result is clamped to the drive range. A non-finite
    measurement resets the derivative and returns the feed-forward drive only.
    """
    vmin = prm[P_VMIN]
    vmax = prm[P_VMAX]
    e = ref - meas
    if not math.isfinite(e):
        st[S_DF + i] = 0.0
        st[S_EPREV + i] = math.nan
        return clamp(prm[P_KFF + i] * ref, vmin, vmax)
    ep = st[S_EPREV + i]
    if not math.isfinite(ep):
        ep = e
    df = prm[P_DA + i] * st[S_DF + i] + prm[P_DB + i] * (e - ep)
    st[S_DF + i] = df
    st[S_EPREV + i] = e
    v = prm[P_KFF + i] * ref + prm[P_KP + i] * e + prm[P_KD + i] * df
    return clamp(v, vmin, vmax)


# supervise() checks the four sources' counters unrolled (the every-cycle fast path)
assert N_REQ_SRC == 4, "update the unrolled request check in supervise()"


@njit(cache=True)
def take_requests(st):
    """Acknowledge the fault requests posted by Python (:mod:`rigd.loop.requests`).

    Source ``s`` owns ``st[S_FREQ + 3 s]`` (request counter) and ``st[S_FREQ + 3 s + 1]``
    (code); the kernel owns ``st[S_FREQ + 3 s + 2]`` (acknowledged counter). Nothing is cleared
    by the reader, so a request posted at any moment is seen by this or the next cycle.
    Every pending request is latched (:func:`latch`: the first wins, the others are listed);
    returns the code of the first pending request (0: none).
    """
    code = 0
    for s in range(N_REQ_SRC):
        b = S_FREQ + 3 * s
        req = st[b]
        if req != st[b + 2]:
            st[b + 2] = req
            c = int(st[b + 1])
            latch(st, c, -1)
            if code == 0:
                code = c
    return code


@njit(cache=True)
def status_fault(st):
    """The fast driver's status bits (``drv_status``) as (fault code, bits), or (0, -1)."""
    status = st[S_Y + IN_STATUS]
    if math.isfinite(status) and status != 0.0:
        bits = int(status)
        if bits & FC.STATUS_ENCODER:
            return FC.ENCODER_LOST, -1
        return FC.DRIVER_STATUS, bits
    return 0, -1


@njit(cache=True)
def supervise(prm, st):
    """Supervisor checks on the calibrated frame ``st[S_Y:S_Y + N_IN]``; returns (fault code,
    detail) or (0, -1).

    Also updates the check counters in ``st`` (stale frames, frozen encoder, valve tracking).
    """
    # every cycle: a cheap look whether any source's request counter moved (rarely)
    if st[S_FREQ] != st[S_FREQ + 2] or st[S_FREQ + 3] != st[S_FREQ + 5] or \
            st[S_FREQ + 6] != st[S_FREQ + 8] or st[S_FREQ + 9] != st[S_FREQ + 11]:
        ext = take_requests(st)
        if ext != 0:
            return ext, -1
    code = 0
    detail = -1
    # NaN / Inf on the sensors the loop uses
    for ch in (IN_E_X, IN_E_Y, IN_YP1, IN_YP1 + 1, IN_YP1 + 2, IN_YP1 + 3, IN_PHI):
        if not math.isfinite(st[S_Y + ch]):
            return FC.SENSOR_NAN, ch
    if prm[P_SUP_ON] == 0.0:
        return status_fault(st)     # the driver's own report, like NaN, is always checked
    for ch in (IN_E_X, IN_E_Y):
        if st[S_Y + ch] < prm[P_E_MIN] or st[S_Y + ch] > prm[P_E_MAX]:
            return FC.SENSOR_RANGE, ch
    for i in range(4):
        ch = IN_YP1 + i
        if st[S_Y + ch] < prm[P_Y_MIN] or st[S_Y + ch] > prm[P_Y_MAX]:
            return FC.SENSOR_RANGE, ch
    code, detail = status_fault(st)
    if code != 0:
        return code, detail
    # stale frame: the driver's own counter did not advance
    dseq = st[S_Y + IN_SEQ]
    if prm[P_STALE_N] > 0.0 and math.isfinite(dseq):
        if dseq == st[S_LAST_DRVSEQ]:
            st[S_STALE_CNT] += 1.0
            if st[S_STALE_CNT] > prm[P_STALE_N]:
                code = FC.STALE_FRAME
        else:
            st[S_STALE_CNT] = 0.0
        st[S_LAST_DRVSEQ] = dseq
    # lost encoder: phi frozen while the shaft turns
    omega = st[S_Y + IN_OMEGA]
    if prm[P_ENC_N] > 0.0 and math.isfinite(omega) and abs(omega) > prm[P_ENC_OMEGA]:
        if st[S_Y + IN_PHI] == st[S_LAST_PHI]:
            st[S_PHI_CNT] += 1.0
            if st[S_PHI_CNT] > prm[P_ENC_N] and code == 0:
                code = FC.ENCODER_LOST
        else:
            st[S_PHI_CNT] = 0.0
    else:
        st[S_PHI_CNT] = 0.0
    st[S_LAST_PHI] = st[S_Y + IN_PHI]
    if code != 0:
        return code, detail
    # shaft displacement relative to the bearing centre vs the film gap
    dx = st[S_Y + IN_E_X] - prm[P_CX]
    dy = st[S_Y + IN_E_Y] - prm[P_CY]
    if dx * dx + dy * dy > prm[P_GAP_MAX] * prm[P_GAP_MAX]:
        return FC.SHAFT_DISPLACEMENT, -1
    return 0, -1


@njit(cache=True)
def latch(st, code, detail):
    """Latch ``code`` unless a fault is already latched, and append it to the fault log; a
    fault of another kind while one is latched is only appended (once per kind until the
    reset: ``st[S_LISTED]`` has a bit per kind listed), so the log shows every fault."""
    if code == 0:
        return
    bit = 1 << code
    listed = int(st[S_LISTED])
    if st[S_FAULT] != 0.0:
        if listed & bit:
            return
        st[S_LISTED] = float(listed | bit)
    else:
        st[S_FAULT] = code
        st[S_FAULT_SEQ] = st[S_SEQ]
        st[S_FAULT_DETAIL] = detail
        st[S_LISTED] = float(bit)
    k = int(st[S_NFAULT]) % FLOG_N
    st[S_FLOG + 3 * k] = st[S_SEQ]
    st[S_FLOG + 3 * k + 1] = code
    st[S_FLOG + 3 * k + 2] = detail
    st[S_NFAULT] += 1.0


@njit(cache=True)
def take_safe(sw, st):
    """Take a SAFE request from the shared word ``sw`` (:mod:`rigd.loop.safeword`), before
    the cycle: latch ``operator_safe`` so this very cycle runs in the safe state, and
    acknowledge it (the cycle, the fault in force). Every cycle: one store, two loads, one
    compare."""
    seq = st[S_SEQ]
    sw[W_SEQ] = int(seq)
    req = sw[W_REQ]
    if req != st[S_SAFE_SEEN]:
        st[S_SAFE_SEEN] = req
        st[S_SAFE_GEN] += 1.0
        latch(st, FC.OPERATOR_SAFE, -1)
        sw[W_ACK_SEQ] = int(seq)
        sw[W_ACK_CODE] = int(st[S_FAULT])
        sw[W_ACK_FAULT_SEQ] = int(st[S_FAULT_SEQ])
        sw[W_ACK_N] += 1
    stall = sw[W_STALL_REQ]
    if stall != st[S_STALL_SEEN]:      # the watchdog process saw the loop stand still
        st[S_STALL_SEEN] = stall
        latch(st, FC.LOOP_STALL, -1)
    # the fault in force, for readers in other processes (status reads its own writes)
    sw[W_FAULT] = int(st[S_FAULT])
    sw[W_FAULT_SEQ] = int(st[S_FAULT_SEQ])


@njit(cache=True)
def watch_cycle(prm, st, sw, now_ns):
    """Liveness of the real-time cycle, measured by the cycle itself (:mod:`rigd.loop.liveness`).

    ``now_ns`` is this cycle's wake-up (``CLOCK_MONOTONIC``); the previous one is in the safe
    word (``W_CYCLE_NS``, what other processes read the loop's age from). A gap between two
    cycles longer than the stall bound latches ``loop_stall``. The control time lost since the
    previous cycle — the gap beyond two periods: a cycle up to one period late is a late
    update, beyond that the outputs stood with no update at all — goes into a leaky bucket
    (decay ``exp(-T/W)`` per cycle); beyond the storm bound it latches ``overrun_storm``.
    O(1): a few loads and stores, a multiply, two compares.
    """
    prev = sw[W_CYCLE_NS]
    sw[W_CYCLE_NS] = now_ns
    lost = st[S_LOST_NS] * prm[P_LOST_DECAY]
    if prev > 0 and st[S_SEQ] >= prm[P_GRACE_N]:   # not during the start-up grace
        gap = float(now_ns - prev)
        # up to one period late is a late update (jitter); beyond, no update at all
        absent = gap - 2.0 * prm[P_PERIOD_NS]
        if absent > 0.0:
            lost += absent
        if prm[P_STALL_NS] > 0.0 and gap > prm[P_STALL_NS]:
            sw[W_LOOP_GAP_NS] = int(gap)
            sw[W_STALL_FROM] = int(st[S_SEQ]) - 1
            latch(st, FC.LOOP_STALL, -1)
    st[S_LOST_NS] = lost
    if prm[P_STORM_NS] > 0.0 and lost > prm[P_STORM_NS]:
        latch(st, FC.OVERRUN_STORM, -1)


@njit(cache=True, inline="always")
def mark_fast_invalid(ring, r, omega_too, pinj_too):
    """Row ``r``: the fast driver's channels (sensors and what is derived from them) NaN —
    an invalid sample, never the held value; Ω and P_I too when no slow driver provides them."""
    nan = math.nan
    ring[r, R_EX] = nan
    ring[r, R_EY] = nan
    for i in range(4):
        ring[r, R_YP1 + i] = nan
    ring[r, R_PHI] = nan
    ring[r, R_FX] = nan
    ring[r, R_FY] = nan
    ring[r, R_UX] = nan
    ring[r, R_UY] = nan
    if omega_too:
        ring[r, R_OMEGA] = nan
    if pinj_too:
        ring[r, R_PINJ] = nan


@njit(cache=True)
def cycle(fin, prm, st, drive, ring, ex, ey):
    """One loop cycle from the input frame ``fin`` to the drive vector and one ring frame.

    Parameters
    ----------
    fin : float64[N_IN]
        Input frame as the fast drivers delivered it (driver units; calibrated here).
    prm, st : float64 arrays
        Parameters and state (:mod:`rigd.loop.layout`).
    drive : float64[4]
        Output: valve drive voltages, V, clamped to the drive range.
    ring : float64[(ring_n, N_REC)]
        Recorder ring buffer; the frame goes to row ``st[S_W] % ring_n``. When the writer has
        not freed a row the frame is counted in ``st[S_DROPPED]`` and RECORDER_OVERFLOW latches.
    ex, ey : float
        Experiment excitation added to r_x, r_y this cycle, V.
    """
    # calibrate (driver units -> µm, V, N) and overlay the latest slow-driver values
    for c in range(N_IN):
        st[S_Y + c] = fin[c] * prm[P_CAL_G + c] + prm[P_CAL_O + c]
    if math.isfinite(st[S_SLOW_OMEGA]):
        st[S_Y + IN_OMEGA] = st[S_SLOW_OMEGA]
    if math.isfinite(st[S_SLOW_PINJ]):
        st[S_Y + IN_P_INJ] = st[S_SLOW_PINJ]

    # no fresh data from the fast driver (it says so, or the frame repeats): the cycle runs
    # on the held values, the record gets NaN for the driver's channels (docs/data.md)
    status = st[S_Y + IN_STATUS]
    nodata = math.isfinite(status) and (int(status) & FC.STATUS_NO_DATA) != 0

    # supervisor; valve tracking compares the previous cycle's reference with the position
    code, detail = supervise(prm, st)
    if code == 0 and prm[P_SUP_ON] != 0.0 and prm[P_VERR_N] > 0.0:
        for i in range(4):
            if abs(st[S_RP_PREV + i] - st[S_Y + IN_YP1 + i]) > prm[P_VERR_V]:
                st[S_VERR_CNT + i] += 1.0
                if st[S_VERR_CNT + i] > prm[P_VERR_N] and code == 0:
                    code = FC.VALVE_TRACKING
                    detail = i
            else:
                st[S_VERR_CNT + i] = 0.0
    latch(st, code, detail)
    safe = st[S_FAULT] != 0.0

    # K∞(z) in hot standby on e = -(p - p_eq)
    px = st[S_Y + IN_E_X]
    py = st[S_Y + IN_E_Y]
    ok = math.isfinite(px) and math.isfinite(py)
    if ok and st[S_K_TARGET] == 0.0 and st[S_RAMP] == 0.0:
        if st[S_PEQ_INIT] == 0.0:
            st[S_PEQ_X] = px
            st[S_PEQ_Y] = py
            st[S_PEQ_INIT] = 1.0
        else:  # track the equilibrium while off; frozen (captured) from the enable on
            a = prm[P_PEQ_ALPHA]
            st[S_PEQ_X] += a * (px - st[S_PEQ_X])
            st[S_PEQ_Y] += a * (py - st[S_PEQ_Y])
    e0 = -(px - st[S_PEQ_X]) if ok else 0.0
    e1 = -(py - st[S_PEQ_Y]) if ok else 0.0
    k0, k1 = ss_step(prm, st, e0, e1)
    st[S_K_OUT_X] = k0
    st[S_K_OUT_Y] = k1
    # bumpless blend
    if safe:
        st[S_RAMP] = 0.0
        ex = 0.0
        ey = 0.0
    elif st[S_K_TARGET] > st[S_RAMP]:
        st[S_RAMP] = min(st[S_RAMP] + prm[P_RAMP_STEP], st[S_K_TARGET])
    elif st[S_K_TARGET] < st[S_RAMP]:
        st[S_RAMP] = max(st[S_RAMP] - prm[P_RAMP_STEP], st[S_K_TARGET])
    ramp = st[S_RAMP]
    kx = ramp * k0
    ky = ramp * k1
    rx = kx + ex
    ry = ky + ey
    vmin = prm[P_VMIN]
    vmax = prm[P_VMAX]
    rp1, rp2, rp3, rp4 = eq1(prm[P_R0], rx, ry)
    rp1 = clamp(rp1, vmin, vmax)
    rp2 = clamp(rp2, vmin, vmax)
    rp3 = clamp(rp3, vmin, vmax)
    rp4 = clamp(rp4, vmin, vmax)
    st[S_RP_PREV] = rp1
    st[S_RP_PREV + 1] = rp2
    st[S_RP_PREV + 2] = rp3
    st[S_RP_PREV + 3] = rp4
    drive[0] = pd_step(prm, st, 0, rp1, st[S_Y + IN_YP1])
    drive[1] = pd_step(prm, st, 1, rp2, st[S_Y + IN_YP1 + 1])
    drive[2] = pd_step(prm, st, 2, rp3, st[S_Y + IN_YP1 + 2])
    drive[3] = pd_step(prm, st, 3, rp4, st[S_Y + IN_YP1 + 3])

    # record
    seq = st[S_SEQ]
    ring_n = prm[P_RING_N]
    w = st[S_W]
    if w - st[S_RD] >= ring_n:
        st[S_DROPPED] += 1.0
        latch(st, FC.RECORDER_OVERFLOW, -1)
    else:
        r = int(w) % int(ring_n)
        ring[r, R_SEQ] = seq
        ring[r, R_T] = seq / prm[P_FS]
        ring[r, R_EX] = px
        ring[r, R_EY] = py
        for i in range(4):
            ring[r, R_YP1 + i] = st[S_Y + IN_YP1 + i]
            ring[r, R_V1 + i] = drive[i]
        ring[r, R_PHI] = st[S_Y + IN_PHI]
        ring[r, R_FX] = st[S_Y + IN_F_X]
        ring[r, R_FY] = st[S_Y + IN_F_Y]
        ring[r, R_OMEGA] = st[S_Y + IN_OMEGA]
        ring[r, R_PINJ] = st[S_Y + IN_P_INJ]
        ring[r, R_RX] = rx
        ring[r, R_RY] = ry
        ring[r, R_KX] = kx
        ring[r, R_KY] = ky
        ring[r, R_XX] = ex
        ring[r, R_XY] = ey
        ring[r, R_RP1] = rp1
        ring[r, R_RP1 + 1] = rp2
        ring[r, R_RP1 + 2] = rp3
        ring[r, R_RP1 + 3] = rp4
        ring[r, R_UX] = st[S_Y + IN_YP1 + 1] - st[S_Y + IN_YP1 + 3]
        ring[r, R_UY] = st[S_Y + IN_YP1] - st[S_Y + IN_YP1 + 2]
        ring[r, R_KON] = 1.0 if (st[S_K_TARGET] != 0.0 and not safe) else 0.0
        ring[r, R_FAULT] = st[S_FAULT]
        if nodata or st[S_STALE_CNT] > 0.0:
            mark_fast_invalid(ring, r, not math.isfinite(st[S_SLOW_OMEGA]),
                              not math.isfinite(st[S_SLOW_PINJ]))
        bad = st[S_SLOW_BAD]
        if bad != 0.0:
            b = int(bad)
            if b & 1:
                ring[r, R_OMEGA] = math.nan
            if b & 2:
                ring[r, R_PINJ] = math.nan
        st[S_W] = w + 1.0
    st[S_SEQ] = seq + 1.0


@njit(cache=True, inline="always")
def _hist_add(hist, row, ns):
    if ns < 0:
        ns = 0
    b = ns // H_BIN_NS
    if b >= H_NB:
        hist[row, H_OVER] += 1
    else:
        hist[row, b] += 1
    hist[row, H_COUNT] += 1
    if ns > hist[row, H_MAX]:
        hist[row, H_MAX] = ns


@njit(cache=True)
def rt_cycle(fin, prm, st, drive, ring, exc, exc_i, hist, late_ns, prev_compute_ns, sw,
             now_ns):
    """One cycle on the real-time clock: timing samples into ``hist``, a SAFE request from the
    word ``sw`` (:func:`take_safe`), excitation row ``exc[exc_i]`` (none when ``exc_i < 0``),
    then :func:`cycle`.

    ``late_ns`` is this cycle's wake-up lateness, ``prev_compute_ns`` the previous cycle's
    compute time (read to write, drivers included; < 0: none yet).
    """
    _hist_add(hist, 1, late_ns)
    if prev_compute_ns >= 0:
        _hist_add(hist, 0, prev_compute_ns)
    watch_cycle(prm, st, sw, now_ns)
    take_safe(sw, st)
    if exc_i >= 0:
        cycle(fin, prm, st, drive, ring, exc[exc_i, 0], exc[exc_i, 1])
    else:
        cycle(fin, prm, st, drive, ring, 0.0, 0.0)


def _lockstep_batch(plant_step, pstate, pparams, fin, prm, st, drive, ring, exc, exc_i, n,
                    sw):
    """Run up to ``n`` cycles with the plant kernel in the loop; returns the cycles run.

    Stops early (never drops) when the ring buffer has no free row: the caller lets the writer
    thread drain it and calls again. Stops after the cycle that latches a fault, so that the
    caller sees it at once (a segment ends there, faults are reported). ``exc_i < 0``: no
    excitation; else row ``exc_i + k``. ``sw``: the SAFE word, read every cycle.
    """
    ring_n = prm[P_RING_N]
    nf = st[S_NFAULT]
    done = 0
    for k in range(n):
        if st[S_W] - st[S_RD] >= ring_n:
            break
        take_safe(sw, st)
        if exc_i >= 0:
            cycle(fin, prm, st, drive, ring, exc[exc_i + k, 0], exc[exc_i + k, 1])
        else:
            cycle(fin, prm, st, drive, ring, 0.0, 0.0)
        plant_step(pstate, pparams, drive, fin)
        done += 1
        if st[S_NFAULT] != nf:
            break
    return done


_A1 = types.float64[::1]
_A2 = types.float64[:, ::1]
_W = types.int64[::1]
PLANT_SIG = types.void(_A1, _A1, _A1, _A1)
#: cached variant for plant kernels of the standard signature (float64 C-contiguous 1-D arrays)
lockstep_batch = njit(types.int64(types.FunctionType(PLANT_SIG), _A1, _A1, _A1, _A1, _A1, _A1,
                                  _A2, _A2, types.int64, types.int64, _W),
                      cache=True, nogil=True)(_lockstep_batch)
#: generic variant (any plant kernel signature; compiled per process)
lockstep_batch_generic = njit(nogil=True)(_lockstep_batch)


def hist_new() -> np.ndarray:
    """A zeroed timing histogram (see :mod:`rigd.loop.layout`)."""
    return np.zeros((2, H_NB + 3), dtype=np.int64)
