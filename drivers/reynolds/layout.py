"""Array layout of the physics-grade plant's kernel: slots of the ``params`` header and of the
scalar regions.

Array sizes depend on the grid and the number of modes, so every offset is stored in the
``params`` header by :func:`rigd_drivers.reynolds.params.build_layout`: ``H_*`` are fixed
header slots, ``O_*`` header slots holding block-relative offsets, ``T_*``/``W_*`` header slots
holding state offsets (T: plant state, W: work arrays); ``SC_*`` index the scalars of the
parameter block, ``ST_*`` the scalars of the state.
"""

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
(O_GEO, O_CS, O_WTS, O_SINV, O_CR, O_PHIB, O_PHID, O_CB, O_VPHI, O_VGAM, O_VOFF, O_SC,
 O_FST) = range(_h, _h + 13)
_h += 13
# state offsets (stored in the header)
(T_P, T_P1, T_PSI, T_PSI1, T_Q, T_V, T_Q1, T_V1, T_XV, T_VPREV, T_AF0, T_SC, T_FRAME,
 W_RATE, W_JA, W_JB, W_JC, W_DRX, W_DRY, W_D, W_DINV, W_E, W_T1, W_T2, W_FB, W_G, W_GV,
 W_MD, W_DMD, W_AF, W_OUT, W_CAP, W_CAPI, W_RK, W_HIST, W_VR, W_TMP) = range(_h, _h + 37)
_h += 37
# feed path (reynolds.feed): chamber pressures now and one sub-step ago (Pa), and work
(T_PC, T_PC1, W_HC, W_FW, W_RC, W_GC, W_PM) = range(_h, _h + 7)
_h += 7
# film and chamber pressures two sub-steps ago (Pa): the Newton predictor's third point
(T_P2, T_PC2) = range(_h, _h + 2)
N_HEADER = _h + 2

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
SC_PSUP_T = 15       # supply set point P_I + P_atm, Pa (SC_PSUP follows it at the slew rate)
SC_SLEW = 16         # supply slew, Pa per loop period (0: the supply jumps)
SC_NEWTON_MAX = 17   # at most this many Newton iterations per sub-step
SC_RES_TOL = 18      # converged: residual after the update below this (pressure change / p_a)
N_SC = 20

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
ST_RES = 15          # residual after the last Newton update of the last sub-step (/ p_a)
ST_FAIL = 16         # sub-steps whose residual stayed above SC_RES_TOL after SC_NEWTON_MAX
ST_XB = 17           # 2: bearing displacement, m
ST_PSUP = 19         # the supply pressure now (on its way to the set point), Pa
ST_STOP = 20         # drv_status bits (STATUS_*): non-zero once the plant stopped
ST_STOP_SEQ = 21     # drv_seq of the sample at which it stopped
ST_NAN = 22          # sub-steps whose solution was not finite
ST_HFLOOR = 23       # sub-steps that ended with the film thickness floored somewhere (H_MIN c)
ST_PFLOOR = 24       # sub-steps in which a Newton update was clipped at 0.2 p_a
ST_NEWTON_IT = 25    # Newton iterations, all sub-steps
ST_NSUB = 26         # sub-steps integrated
ST_EPS_MAX = 27      # largest journal eccentricity ratio ε seen at the end of a sub-step
N_STSC = 32

# --- drv_status bits of this plant (bits 0 and 1 keep the loop's meaning: encoder, sensor) ----
STATUS_CONTACT = 1 << 4     # the journal reached the bearing wall (ε ≥ 1): the plant stopped
STATUS_DIVERGED = 1 << 5    # the film + shaft solution was not finite: the plant stopped
