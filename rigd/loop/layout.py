"""Index layout of the loop's preallocated float64 arrays (parameters ``prm``, state ``st``).

The numba kernels (:mod:`rigd.loop.cycle`) take a handful of flat float64 arrays instead of
many small ones: every argument costs dispatch time on the real-time path. These module-level
integers are compile-time constants inside the kernels.

``prm`` holds what the configuration and the controller file set (written only between cycles);
``st`` holds what the cycle mutates, plus the fault-request counters other threads post into
(:mod:`rigd.loop.requests`: each slot has one writer; the kernel never clears them).
"""

from __future__ import annotations

from rigd.controller import MAX_ORDER
from rigd.frame import N_IN

#: largest K∞ order the loop reserves room for (the controller checks refuse more).
K_NMAX = MAX_ORDER

# --- parameters ---------------------------------------------------------------------------
P_FS = 0            # loop rate, Hz
P_R0 = 1            # r0 of Eq. 1, V
P_VMIN = 2          # drive / valve-reference range, V
P_VMAX = 3
P_RAMP_STEP = 4     # K∞ blend ramp increment per cycle (1 / (ramp_s * fs))
P_PEQ_ALPHA = 5     # p_eq tracking filter coefficient while K∞ is off (per cycle)
P_KP = 6            # 4 proportional gains, V/V
P_KD = 10           # 4 derivative gains, V·s/V
P_DA = 14           # 4 derivative filter pole a = tf / (tf + T)
P_DB = 18           # 4 derivative filter input gain 1 / (tf + T), 1/s
P_KFF = 22          # 4 reference feed-forward gains, V/V
P_CAL_G = 26        # N_IN calibration gains (driver unit -> engineering unit)
P_CAL_O = P_CAL_G + N_IN   # N_IN calibration offsets
_S = P_CAL_O + N_IN
P_SUP_ON = _S + 0   # 1 = supervisor checks active
P_E_MIN = _S + 1    # shaft displacement sensor range, µm
P_E_MAX = _S + 2
P_Y_MIN = _S + 3    # valve position sensor range, V
P_Y_MAX = _S + 4
P_GAP_MAX = _S + 5  # allowed radial displacement from the centre, µm
P_CX = _S + 6       # bearing centre in sensor coordinates, µm
P_CY = _S + 7
P_STALE_N = _S + 8  # repeated drv_seq tolerated this many cycles
P_ENC_OMEGA = _S + 9   # encoder check active above this speed, rpm
P_ENC_N = _S + 10      # phi frozen this many cycles -> encoder lost
P_VERR_V = _S + 11     # valve tracking error limit, V
P_VERR_N = _S + 12     # ... tolerated this many cycles
P_RING_N = _S + 13     # ring buffer capacity, frames
P_KN = _S + 14         # K∞ order n (0 = no controller: zero output)
P_KA = _S + 16                      # A, n x n row-major (room for K_NMAX^2)
P_KB = P_KA + K_NMAX * K_NMAX       # B, n x 2
P_KC = P_KB + K_NMAX * 2            # C, 2 x n
P_KD_MAT = P_KC + 2 * K_NMAX        # D, 2 x 2
#: liveness (rigd.loop.liveness): a gap between two real-time cycles longer than this latches
#: loop_stall, ns (0: off)
P_STALL_NS = P_KD_MAT + 4
P_LOST_DECAY = P_STALL_NS + 1   # per-cycle decay of the lost-control-time bucket, exp(-T/W)
P_STORM_NS = P_LOST_DECAY + 1   # lost control time in the bucket that latches overrun_storm, ns
P_PERIOD_NS = P_STORM_NS + 1    # the loop period, ns
P_GRACE_N = P_PERIOD_NS + 1     # cycles from the start not measured (start-up transient)
N_PRM = P_GRACE_N + 1

# --- state --------------------------------------------------------------------------------
S_SEQ = 0           # number of the next cycle (= frames produced so far)
S_FAULT = 1         # latched fault code (0 = none)
S_FAULT_SEQ = 2     # cycle at which it latched
S_NFAULT = 3        # number of latches since start (monitor thread reads new log entries)
S_SLOW_BAD = 4      # slow channels without valid data (bit 0: omega_rpm, bit 1: p_inj_bar):
                    # recorded as NaN (written by the slow-driver threads; rigd.loop.slow)
S_K_TARGET = 5      # 1 = K∞ requested on, 0 = off
S_RAMP = 6          # K∞ blend factor in [0, 1]
S_PEQ_X = 7         # p_eq, µm (tracked while off, frozen while on)
S_PEQ_Y = 8
S_EPREV = 9         # 4 previous PD errors, V
S_DF = 13           # 4 filtered derivatives, V/s
S_LAST_DRVSEQ = 17
S_STALE_CNT = 18
S_LAST_PHI = 19
S_PHI_CNT = 20
S_VERR_CNT = 21     # 4 counters
S_W = 25            # frames written into the ring (total)
S_RD = 26           # frames consumed from the ring by the writer thread (total)
S_DROPPED = 27      # frames that found the ring full (real-time clock only): never silent
S_SLOW_OMEGA = 28   # latest slow-driver values (NaN = not provided: keep the fast driver's)
S_SLOW_PINJ = 29
S_FAULT_DETAIL = 30  # channel / valve index of the latched fault (-1 if none)
S_PEQ_INIT = 31     # 0 until p_eq tracking has been seeded with a first sample
S_K_OUT_X = 32      # last K∞ output before the blend (for status)
S_K_OUT_Y = 33
S_RP_PREV = 34      # 4 valve references of the previous cycle (valve tracking check)
S_SAFE_SEEN = 38    # the safe word's request value last taken (rigd.loop.safeword; private)
S_SAFE_GEN = 39     # SAFE requests taken so far: a command posted before a change is dropped
S_FLOG = 40         # fault log: FLOG_N entries of (seq, code, detail)
FLOG_N = 16
#: fault requests from Python, one triple per source (rigd.loop.requests): request counter
#: and code (written only by that source), acknowledged counter (written only by the kernel)
N_REQ_SRC = 4
S_FREQ = S_FLOG + 3 * FLOG_N
S_X = S_FREQ + 3 * N_REQ_SRC  # K∞ state x (K_NMAX)
S_XN = S_X + K_NMAX           # scratch for x+ (K_NMAX)
S_Y = S_XN + K_NMAX           # calibrated input frame (N_IN)
S_LISTED = S_Y + N_IN         # bit per fault code already in the log since the latch
S_STALL_SEEN = S_LISTED + 1   # the safe word's stall request value last taken (private)
S_LOST_NS = S_STALL_SEEN + 1  # lost control time, leaky bucket (rigd.loop.liveness), ns
N_ST = S_LOST_NS + 1

# --- timing histograms (int64, shape (2, H_NB + 3)) ----------------------------------------
H_COMPUTE = 0       # row: per-cycle compute time
H_LATE = 1          # row: wake-up lateness
H_NB = 20000        # bins of H_BIN_NS each; then overflow, count, max (ns)
H_BIN_NS = 100
H_OVER = H_NB
H_COUNT = H_NB + 1
H_MAX = H_NB + 2
