"""The kernel state: the preallocated arrays the compiled cycle works on, and their one owner.

:class:`KernelState` holds the parameter array ``prm`` (written from the configuration before
the loop runs, and by controller swaps at a cycle boundary), the state array ``st`` (mutated by
the cycle), the input frame ``fin``, the drive vector ``drive``, the timing histogram ``hist``
and the safe drive. Layouts in :mod:`rigd.loop.layout`.

Everything that may run while the loop cycles is done on preallocated views: a controller is
*packed* into a ``prm``-shaped block in the caller's thread (:func:`pack_controller`) and copied
in whole at a cycle boundary (:meth:`KernelState.swap_controller`).
"""

from __future__ import annotations

import numpy as np

from rigd import frame as F
from rigd.loop import layout as L
from rigd.loop.cycle import hist_new

#: the slice of ``prm`` a controller occupies: order, A, B, C, D
_K0, _K1 = L.P_KN, L.P_KD_MAT + 4


class PackedController:
    """A validated controller laid out as the ``prm[P_KN:P_KD_MAT + 4]`` block (made off the loop).

    Parameters
    ----------
    ctrl : rigd.controller.Controller or None
        None: no controller (zero output).
    """

    __slots__ = ("controller", "block")

    def __init__(self, ctrl) -> None:
        self.controller = ctrl
        b = np.zeros(_K1 - _K0)
        if ctrl is not None:
            n = ctrl.order
            o = -_K0
            b[L.P_KN + o] = n
            b[L.P_KA + o:L.P_KA + o + n * n] = np.asarray(ctrl.A, float).ravel()
            b[L.P_KB + o:L.P_KB + o + 2 * n] = np.asarray(ctrl.B, float).ravel()
            b[L.P_KC + o:L.P_KC + o + 2 * n] = np.asarray(ctrl.C, float).ravel()
            b[L.P_KD_MAT + o:L.P_KD_MAT + o + 4] = np.asarray(ctrl.D, float).ravel()
        self.block = b


class KernelState:
    """Owner of the cycle's arrays (see module docstring).

    Parameters
    ----------
    config : rigd.rigconfig.RigConfig
    ring_frames : int
        Recorder ring capacity (``prm[P_RING_N]``).
    """

    def __init__(self, config, ring_frames: int) -> None:
        self.fs = config.loop.fs_hz
        self.prm = np.zeros(L.N_PRM)
        self.st = np.zeros(L.N_ST)
        self.fin = np.zeros(F.N_IN)
        self.drive = np.zeros(F.N_OUT)
        self.hist = hist_new()
        self.safe_drive = np.zeros(F.N_OUT)
        self._fill(config)
        self.prm[L.P_RING_N] = ring_frames
        # preallocated views for the loop-thread operations
        self._k_prm = self.prm[_K0:_K1]
        self._k_x = self.st[L.S_X:L.S_X + L.K_NMAX]
        self._verr = self.st[L.S_VERR_CNT:L.S_VERR_CNT + 4]
        self.controller = None

    def _fill(self, c) -> None:
        p, T = self.prm, 1.0 / self.fs
        p[L.P_FS] = self.fs
        p[L.P_R0] = c.loop.r0_v
        p[L.P_VMIN], p[L.P_VMAX] = c.loop.drive_v
        p[L.P_RAMP_STEP] = 1.0 if c.loop.k_ramp_s == 0 else T / c.loop.k_ramp_s
        p[L.P_PEQ_ALPHA] = 1.0 - np.exp(-T / c.loop.peq_tau_s)
        for i, v in enumerate(c.valves):
            p[L.P_KP + i], p[L.P_KD + i], p[L.P_KFF + i] = v.kp, v.kd, v.kff
            p[L.P_DA + i] = v.tf_s / (v.tf_s + T)
            p[L.P_DB + i] = 1.0 / (v.tf_s + T)
        g, o = c.calibration_arrays()
        p[L.P_CAL_G:L.P_CAL_G + F.N_IN] = g
        p[L.P_CAL_O:L.P_CAL_O + F.N_IN] = o
        s = c.supervisor
        p[L.P_SUP_ON] = 1.0 if s.enabled else 0.0
        p[L.P_E_MIN], p[L.P_E_MAX] = s.e_range_um
        p[L.P_Y_MIN], p[L.P_Y_MAX] = s.y_p_range_v
        p[L.P_GAP_MAX] = s.max_gap_fraction * s.film_gap_um
        p[L.P_CX], p[L.P_CY] = s.centre_um
        p[L.P_STALE_N] = s.stale_frames
        p[L.P_ENC_OMEGA] = s.encoder_min_omega_rpm
        p[L.P_ENC_N] = round(s.encoder_frozen_s * self.fs)
        p[L.P_VERR_V] = s.valve_error_v
        p[L.P_VERR_N] = round(s.valve_error_s * self.fs)
        st = self.st
        st[L.S_EPREV:L.S_EPREV + 4] = np.nan
        st[L.S_RP_PREV:L.S_RP_PREV + 4] = c.loop.r0_v
        st[L.S_LAST_DRVSEQ] = np.nan
        st[L.S_SLOW_OMEGA] = st[L.S_SLOW_PINJ] = np.nan
        st[L.S_FAULT_DETAIL] = -1
        # the safe state's drive (docs/loop.md): each valve's feed-forward at r_p = r0
        lo, hi = c.loop.drive_v
        for i, v in enumerate(c.valves):
            self.safe_drive[i] = min(max(v.kff * c.loop.r0_v, lo), hi)

    # --- loop thread (or before the loop runs) -------------------------------------------
    def swap_controller(self, packed: PackedController) -> None:
        """Copy a packed controller into ``prm`` and zero its state x.

        Runs in: loop thread (at a cycle boundary, K∞ blended out) — O(1) (one copy of a
        fixed-size block), allocation-free, non-blocking.
        """
        np.copyto(self._k_prm, packed.block)
        self._k_x.fill(0.0)
        self.controller = packed.controller

    def reset_fault(self) -> None:
        """Clear the latched fault and the check counters; K∞ stays off until re-enabled.

        Runs in: loop thread — O(1), allocation-free, non-blocking.
        """
        st = self.st
        st[L.S_FAULT] = 0.0
        st[L.S_FAULT_DETAIL] = -1.0
        st[L.S_LISTED] = 0.0        # a fault still present after the reset is listed again
        st[L.S_STALE_CNT] = 0.0
        st[L.S_PHI_CNT] = 0.0
        self._verr.fill(0.0)
        st[L.S_K_TARGET] = 0.0

    # --- queries (any thread) --------------------------------------------------------------
    @property
    def fault(self) -> int:
        return int(self.st[L.S_FAULT])

    @property
    def seq(self) -> int:
        return int(self.st[L.S_SEQ])
