"""Channel layout of the loop's per-cycle vectors and of the recorded frame.

Fast drivers fill the *input frame* (``IN_*`` indices, float64[N_IN]) every cycle and receive
the *drive vector* (``OUT_*``, float64[N_OUT]): the four valve drive voltages. The recorder
stores one *record frame* per cycle with the channels of :data:`RECORD_CHANNELS`; their names
are those of the interchange CSV (``../shared/data-format.md``) where one exists.

Units: displacements µm, valve references/positions/drives V, angle rad, force N,
speed rpm, pressure bar (manometric), time s.
"""

from __future__ import annotations

# --- input frame: what the fast drivers deliver each cycle --------------------------------
IN_E_X, IN_E_Y = 0, 1                  # shaft displacement at the disc, µm (eddy-current)
IN_YP1, IN_YP2, IN_YP3, IN_YP4 = 2, 3, 4, 5   # measured valve positions y_p,i, V
IN_PHI = 6                             # encoder shaft angle, rad in [0, 2π)
IN_F_X, IN_F_Y = 7, 8                  # impact-hammer force, N (0 when no hammer)
IN_OMEGA = 9                           # shaft speed Ω, rpm (slow channel, latest value)
IN_P_INJ = 10                          # injection pressure P_I, bar (slow channel, latest value)
IN_SEQ = 11                            # driver's own frame counter (stale-frame detection)
IN_STATUS = 12                         # driver status bits (0 = healthy)
N_IN = 13

IN_NAMES = ("e_x", "e_y", "y_p1", "y_p2", "y_p3", "y_p4", "phi", "f_x", "f_y",
            "omega_rpm", "p_inj_bar", "drv_seq", "drv_status")

# --- drive vector: what the loop writes each cycle ----------------------------------------
OUT_V1, OUT_V2, OUT_V3, OUT_V4 = 0, 1, 2, 3   # valve drive voltages, V (clamped)
N_OUT = 4

# --- recorded frame ----------------------------------------------------------------------
#: (name, unit) of every recorded channel, in column order. Append only: files store names.
RECORD_CHANNELS: tuple[tuple[str, str], ...] = (
    ("seq", "1"),            # loop cycle number since start: proves nothing was dropped
    ("t", "s"),              # seq / fs
    ("e_x", "um"), ("e_y", "um"),
    ("y_p1", "V"), ("y_p2", "V"), ("y_p3", "V"), ("y_p4", "V"),
    ("phi", "rad"),
    ("f_x", "N"), ("f_y", "N"),
    ("omega_rpm", "rpm"), ("p_inj_bar", "bar"),
    # lumped references r = K∞ output + excitation (Eq. 1 input)
    ("r_x", "V"), ("r_y", "V"),
    ("k_x", "V"), ("k_y", "V"),          # K∞(z) output alone
    ("x_x", "V"), ("x_y", "V"),          # experiment excitation alone
    ("r_p1", "V"), ("r_p2", "V"), ("r_p3", "V"), ("r_p4", "V"),   # per-valve references (Eq. 1)
    ("u_x", "V"), ("u_y", "V"),          # lumped valve positions (Eq. 1): y_p2-y_p4, y_p1-y_p3
    ("v_1", "V"), ("v_2", "V"), ("v_3", "V"), ("v_4", "V"),       # PD drive outputs
    ("k_on", "1"),           # 1 while K∞ is enabled
    ("fault", "1"),          # latched fault code (0 = none)
)
RECORD_NAMES = tuple(n for n, _ in RECORD_CHANNELS)
RECORD_UNITS = tuple(u for _, u in RECORD_CHANNELS)
N_REC = len(RECORD_CHANNELS)
REC = {name: i for i, name in enumerate(RECORD_NAMES)}  #: name -> column index
