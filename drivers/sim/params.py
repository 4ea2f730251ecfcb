"""Kernel parameter and state arrays of the simulated plant, built from its options.

:class:`ParamBlocks` (and :func:`param_block`) turn (options, Ω, P_I, f_s) into the
active-parameter block of :mod:`rigd_drivers.sim.kernel` (exact ZOH/FOH discretisations
included); :func:`rest_state` gives the plant at rest under a constant drive. The
operating-point part is one compiled call without the GIL (:mod:`.opblock`): an
operating-point change is prepared in another thread while the loop thread cycles.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from rigd.lti import zoh
from rigd_drivers.plant import physics as phys
from rigd_drivers.sim import kernel as k
from rigd_drivers.sim.expm import expm
from rigd_drivers.sim.opblock import fill_operating_point
from rigd_drivers.sim.options import PlantOptions


def bearing_augmented(opts: PlantOptions, omega_rpm: float, p_inj_bar: float):
    """Continuous (A, B_w, C) of bearing + optional extra mode, w = [u_x, u_y, f_x, f_y]."""
    A4, Bu, Bf = phys.bearing_state_matrices(omega_rpm, p_inj_bar)
    A = np.zeros((k.NX, k.NX))
    B = np.zeros((k.NX, k.NW))
    C = np.zeros((2, k.NX))
    A[:4, :4] = A4
    B[:4, :2] = Bu
    B[:4, 2:] = Bf
    C[0, 0] = C[1, 1] = 1.0
    em = opts.effects.extra_mode
    w = 2 * math.pi * em.f_hz
    A[4, 5] = 1.0
    A[5, 4] = -w * w
    A[5, 5] = -2 * em.zeta * w
    if em.enabled:
        B[5, 0] = w * w * em.input_um_per_v[0]
        B[5, 1] = w * w * em.input_um_per_v[1]
        C[0, 4] = em.output[0]
        C[1, 4] = em.output[1]
    return A, B, C


@functools.lru_cache(maxsize=8)
def _valve_block(f_scale: float, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ZOH of the four valves (independent of the operating point: computed once per
    (f_scale, T)); returns read-only Φ (16,), Γ (8,), offsets (4,)."""
    vphi, vgam, voff = np.zeros(16), np.zeros(8), np.zeros(4)
    for i, v in enumerate(phys.valve_params(f_scale)):
        w = v.omega
        Av = np.array([[0.0, 1.0], [-w * w, -2 * v.zeta * w]])
        Bv = np.array([[0.0], [v.gain * w * w]])
        Pv, Gv = zoh(Av, Bv, T, expm=expm)
        vphi[4 * i:4 * i + 4] = Pv.ravel()
        vgam[2 * i:2 * i + 2] = Gv.ravel()
        voff[i] = v.offset_v
    for a in (vphi, vgam, voff):
        a.flags.writeable = False
    return vphi, vgam, voff


class ParamBlocks:
    """Parameter blocks of one plant (options, f_s) at any operating point.

    The entries that do not depend on (Ω, P_I) — sensors, valves, effects, noise — are built
    once, here (the template); each operating point is then one compiled call without the GIL
    (:func:`rigd_drivers.sim.opblock.fill_operating_point`) on a copy of the template, so an
    operating-point change prepared while the loop runs barely holds the GIL.

    Parameters
    ----------
    opts : PlantOptions
    fs : float
        Loop rate, Hz.
    """

    def __init__(self, opts: PlantOptions, fs: float) -> None:
        T = 1.0 / fs
        self.T = T
        self.n_sub = int(opts.substeps)
        b = np.zeros(k.NA)
        # the extra mode's rows and the sensors (the bearing part is written per point)
        A, B, C = bearing_augmented(opts, 0.0, 3.0)
        A[:4, :] = 0.0
        B[:4, :] = 0.0
        self.A_aug, self.B_aug = A, B
        b[k.A_C:k.A_C + 2 * k.NX] = C.ravel()
        b[k.A_NSUB] = self.n_sub
        vphi, vgam, voff = _valve_block(float(opts.valves.f_scale), T)
        b[k.A_VPHI:k.A_VPHI + 16] = vphi
        b[k.A_VGAM:k.A_VGAM + 8] = vgam
        b[k.A_VOFF:k.A_VOFF + 4] = voff
        ef = opts.effects
        self.k3_ratio = ef.cubic_stiffness.ratio_at_gap if ef.cubic_stiffness.enabled else 0.0
        if ef.delay.enabled:
            b[k.A_DELAY] = ef.delay.samples
        if ef.hysteresis.enabled:
            h = ef.hysteresis
            b[k.A_HYST_ON] = 1.0
            b[k.A_HYST_ALPHA] = h.alpha
            b[k.A_HYST_B] = h.alpha / (2.0 * h.h_max_v)
            b[k.A_HYST_HMAX] = h.h_max_v
        if ef.creep.enabled:
            b[k.A_CREEP_ON] = 1.0
            for j in range(2):
                b[k.A_CREEP_A + j] = math.exp(-T / ef.creep.tau_s[j])
                b[k.A_CREEP_F + j] = ef.creep.fraction[j]
        self.unbalance_g_mm = 0.0
        if ef.runout.enabled:
            r = ef.runout
            b[k.A_RO_ON] = 1.0
            b[k.A_RO:k.A_RO + 8] = [r.x_um[0], math.radians(r.x_phase_deg[0]),
                                    r.x_um[1], math.radians(r.x_phase_deg[1]),
                                    r.y_um[0], math.radians(r.y_phase_deg[0]),
                                    r.y_um[1], math.radians(r.y_phase_deg[1])]
            self.unbalance_g_mm = float(r.unbalance_g_mm)    # force (N) set per Ω
            b[k.A_UNB + 1] = math.radians(r.unbalance_phase_deg)
        b[k.A_NOISE_E] = opts.noise.e_um
        b[k.A_NOISE_Y] = opts.noise.y_p_v
        b[k.A_SEED] = float(opts.seed)
        b[k.A_T] = T
        b[k.A_NX] = 6 if opts.effects.extra_mode.enabled else 4
        b.flags.writeable = False
        self.template = b

    def __call__(self, omega_rpm: float, p_inj_bar: float) -> np.ndarray:
        """The active parameter block (float64[NA], a new array) at (Ω rpm, P_I bar).

        Runs in: the preparing thread; the GIL is held only for the copy and the call.
        """
        b = self.template.copy()
        fill_operating_point(b, self.A_aug, self.B_aug, float(omega_rpm), float(p_inj_bar),
                             self.T, self.n_sub, self.k3_ratio, self.unbalance_g_mm)
        return b


def param_block(opts: PlantOptions, omega_rpm: float, p_inj_bar: float,
                fs: float) -> np.ndarray:
    """The active parameter block (float64[NA]) for the kernel at (Ω, P_I) (see
    :class:`ParamBlocks`, which a driver keeps to change operating points cheaply)."""
    return ParamBlocks(opts, fs)(omega_rpm, p_inj_bar)


def rest_state(opts: PlantOptions, block: np.ndarray, omega_rpm: float, p_inj_bar: float,
               drive_v: float) -> np.ndarray:
    """State of the plant at rest with every valve held at ``drive_v`` (V) for a long time."""
    s = np.zeros(k.N_STATE)
    ef = opts.effects
    creep = sum(ef.creep.fraction) if ef.creep.enabled else 0.0
    y = np.zeros(4)
    for i, v in enumerate(phys.valve_params(opts.valves.f_scale)):
        s[k.S_XV + 2 * i] = v.gain * drive_v * (1.0 + creep)
        y[i] = s[k.S_XV + 2 * i] + v.offset_v
        s[k.S_VPREV + i] = drive_v
        if ef.creep.enabled:
            s[k.S_CREEP + 2 * i] = ef.creep.fraction[0] * drive_v
            s[k.S_CREEP + 2 * i + 1] = ef.creep.fraction[1] * drive_v
    u = np.array([y[1] - y[3], y[0] - y[2]])
    s[k.S_UBUF:k.S_UBUF + 2 * k.DMAX] = np.tile(u, k.DMAX)
    s[k.S_W:k.S_W + 2] = u
    # bearing equilibrium: K_id p + F_id·k3|p|²p = B_id u (fixed point; tiny correction)
    bm = phys.bearing_matrices(omega_rpm, p_inj_bar)
    k3 = block[k.A_K3]
    rhs = bm.B_id @ u
    p = np.linalg.solve(bm.K_id, rhs)
    for _ in range(50):
        p = np.linalg.solve(bm.K_id, rhs + bm.F_id @ (-k3 * (p @ p) * p))
    s[k.S_X:k.S_X + 2] = p
    A, B, _ = bearing_augmented(opts, omega_rpm, p_inj_bar)
    if B[5, 0] != 0.0 or B[5, 1] != 0.0:
        s[k.S_X + 4] = -(B[5, :2] @ u) / A[5, 4]
    return s
