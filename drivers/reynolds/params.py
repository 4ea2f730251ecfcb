"""Arrays of the physics-grade plant kernel built from its options.

:func:`build_layout` sizes the ``params`` and ``state`` arrays for a grid and a modal model and
writes every offset into the ``params`` header; :func:`param_block` fills the parameter block
for an operating point (Ω, P_I) — the part swapped in whole by ``set_operating_point``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigd.lti import zoh
from rigd_drivers.plant import physics as phys
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds.feed import NFW, VALVE_COS, VALVE_SIN
from rigd_drivers.reynolds.film import (
    G_AREA,
    G_C,
    G_CAP,
    G_CDA,
    G_CDF,
    G_COMP,
    G_DTH,
    G_DZ,
    G_GAMMA,
    G_MU,
    G_MZ,
    G_N,
    G_NT,
    G_PA,
    G_R,
    G_RT,
    NR,
    NV,
)
from rigd_drivers.reynolds.options import ReynoldsOptions
from rigd_drivers.reynolds.shaft import ShaftGeometry, ShaftModel, build_shaft

R_AIR = 287.05        # J/(kg K)
GAMMA_AIR = 1.4
P_ATM = 1.01325e5     # Pa: P_abs = P_I + P_atm (paper Sec. 2)
#: valve i (Fig. 1): 1 at +y, 2 at +x, 3 at −y, 4 at −x (pairing of Eq. 1)
VALVE_THETA_DEG = (90.0, 0.0, 270.0, 180.0)


@dataclass
class Layout:
    """Sizes and offsets of one plant instance."""

    nt: int
    mz: int
    m: int
    n_params: int
    n_state: int
    header: np.ndarray
    block: dict
    st: dict


def build_layout(nt: int, mz: int, m: int) -> Layout:
    """Offsets for a grid (n_theta × mz half-length cells) and m modal coordinates."""
    n = nt * mz
    blk = {}
    pos = 0

    def take(name, size):
        nonlocal pos
        blk[name] = pos
        pos += size

    take(L.O_GEO, G_N)
    take(L.O_CS, 4 * nt)
    take(L.O_WTS, NV * n)
    take(L.O_SINV, m * m)
    take(L.O_CR, m * m)
    take(L.O_PHIB, 2 * m)
    take(L.O_PHID, 2 * m)
    take(L.O_CB, 4)
    take(L.O_VPHI, 16)
    take(L.O_VGAM, 8)
    take(L.O_VOFF, 4)
    take(L.O_SC, L.N_SC)
    take(L.O_FST, m)
    na = pos
    st = {}
    pos = 0

    def stake(name, size):
        nonlocal pos
        st[name] = pos
        pos += size

    mm = mz * mz
    stake(L.T_P, n)
    stake(L.T_P1, n)
    stake(L.T_PSI, n)
    stake(L.T_PSI1, n)
    stake(L.T_Q, m)
    stake(L.T_V, m)
    stake(L.T_Q1, m)
    stake(L.T_V1, m)
    stake(L.T_XV, 8)
    stake(L.T_VPREV, 4)
    stake(L.T_AF0, 4)
    stake(L.T_SC, L.N_STSC)
    from rigd.frame import N_IN
    stake(L.T_FRAME, N_IN)
    stake(L.W_RATE, n)
    stake(L.W_JA, n)
    stake(L.W_JB, nt * mm)
    stake(L.W_JC, n)
    stake(L.W_DRX, n)
    stake(L.W_DRY, n)
    stake(L.W_D, n * (NR + 1))
    stake(L.W_DINV, nt * mm)
    stake(L.W_E, nt * mm)
    stake(L.W_T1, mm)
    stake(L.W_T2, mm)
    stake(L.W_FB, mm)
    stake(L.W_G, mm)
    stake(L.W_GV, mz * (NR + 1))
    stake(L.W_MD, NV)
    stake(L.W_DMD, NV)
    stake(L.W_AF, NV)
    stake(L.W_OUT, 1)
    stake(L.W_CAP, NR * NR)
    stake(L.W_CAPI, NR * NR)
    stake(L.W_RK, m)
    stake(L.W_HIST, n)
    stake(L.W_VR, 2 * NR)
    stake(L.W_TMP, 2 * m)
    stake(L.T_PC, NV)
    stake(L.T_PC1, NV)
    stake(L.W_HC, NV)
    stake(L.W_FW, NFW * NV)
    stake(L.W_RC, NV)
    stake(L.W_GC, NV)
    stake(L.W_PM, NV)
    stake(L.T_P2, n)
    stake(L.T_PC2, NV)
    n_state = pos
    h = np.zeros(L.N_HEADER)
    act = L.N_HEADER
    h[L.H_ACT] = act
    h[L.H_STG] = act + na
    h[L.H_SCR] = act + 2 * na
    h[L.H_NA] = na
    h[L.H_NT] = nt
    h[L.H_MZ] = mz
    h[L.H_M] = m
    for slot, off in blk.items():
        h[slot] = off
    for slot, off in st.items():
        h[slot] = off
    return Layout(nt, mz, m, act + 3 * na, n_state, h, blk, st)


def geometry_vector(opts: ReynoldsOptions) -> np.ndarray:
    """The film's ``geo`` vector (SI units) for the options' grid and bearing."""
    b = opts.bearing
    nt = opts.grid.n_theta
    mz = opts.grid.n_z // 2
    R = b.radius_mm * 1e-3
    g = np.zeros(G_N)
    g[G_NT] = nt
    g[G_MZ] = mz
    g[G_R] = R
    g[G_DTH] = 2 * math.pi / nt
    g[G_DZ] = 0.5 * b.length_mm * 1e-3 / mz
    g[G_C] = b.clearance_um * 1e-6
    g[G_MU] = b.viscosity_pa_s
    g[G_PA] = b.ambient_pa
    g[G_AREA] = R * g[G_DTH] * g[G_DZ]
    g[G_RT] = R_AIR * b.temperature_k
    g[G_GAMMA] = GAMMA_AIR
    g[G_CDA] = b.discharge_coefficient * math.pi * (b.orifice_diameter_mm * 1e-3) ** 2 / 4
    f = opts.feed
    d = f.hole_diameter_mm * 1e-3
    g[G_COMP] = 1.0 if f.compensation == "inherent" else 0.0
    g[G_CDF] = f.discharge_coefficient * math.pi * d * (1.0 if g[G_COMP] else d / 4)
    g[G_CAP] = f.chamber_volume_mm3 * 1e-9 / g[G_RT]
    return g


def trig_vector(nt: int) -> np.ndarray:
    """cos, sin at the cell centres θ_i = (i + ½)Δθ and at the faces θ_{i+½} = (i + 1)Δθ."""
    dth = 2 * math.pi / nt
    tc = (np.arange(nt) + 0.5) * dth
    tf = (np.arange(nt) + 1.0) * dth
    return np.concatenate([np.cos(tc), np.sin(tc), np.cos(tf), np.sin(tf)])


def feed_weights(opts: ReynoldsOptions) -> np.ndarray:
    """Orifice patch weights (NV × N, rows sum to 1): exact overlap of each cell with the
    patch |θ − θ_i| ≤ half-width, 0 ≤ z ≤ half-length (half bearing)."""
    nt = opts.grid.n_theta
    mz = opts.grid.n_z // 2
    b = opts.bearing
    dth = 2 * math.pi / nt
    dz = 0.5 * b.length_mm * 1e-3 / mz
    hw = math.radians(b.feed_half_width_deg)
    hl = min(b.feed_half_length_mm * 1e-3, 0.5 * b.length_mm * 1e-3)
    W = np.zeros((NV, nt * mz))
    for v, th in enumerate(VALVE_THETA_DEG):
        assert abs(math.cos(math.radians(th)) - VALVE_COS[v]) < 1e-12
        assert abs(math.sin(math.radians(th)) - VALVE_SIN[v]) < 1e-12
        t0 = math.radians(th)
        for i in range(nt):
            lo, hi = i * dth, (i + 1) * dth
            ov = 0.0
            for shift in (-2 * math.pi, 0.0, 2 * math.pi):
                a, bb = t0 - hw + shift, t0 + hw + shift
                ov += max(0.0, min(hi, bb) - max(lo, a))
            if ov == 0.0:
                continue
            for j in range(mz):
                oz = max(0.0, min((j + 1) * dz, hl) - j * dz)
                W[v, i * mz + j] = ov * oz
        W[v] /= W[v].sum()
    return W.ravel()


def shaft_model(opts: ReynoldsOptions) -> ShaftModel:
    return build_shaft(ShaftGeometry(n_modes=opts.modes))


def param_block(opts: ReynoldsOptions, lay: Layout, shaft: ShaftModel, omega_rpm: float,
                p_inj_bar: float, fs: float) -> np.ndarray:
    """The parameter block at (Ω, P_I): geometry, shaft step matrices, valves, scalars."""
    b = np.zeros(int(lay.header[L.H_NA]))
    o = lay.block
    g = geometry_vector(opts)
    b[o[L.O_GEO]:o[L.O_GEO] + G_N] = g
    b[o[L.O_CS]:o[L.O_CS] + 4 * lay.nt] = trig_vector(lay.nt)
    n = lay.nt * lay.mz
    b[o[L.O_WTS]:o[L.O_WTS] + NV * n] = feed_weights(opts)
    T = 1.0 / fs
    dt = T / opts.substeps
    al = 3.0 / (2.0 * dt)
    w = omega_rpm * 2 * math.pi / 60.0
    C, K = shaft.matrices(w)
    m = lay.m
    S = al * al * np.eye(m) + al * C + K
    Sinv = np.linalg.inv(S)
    Pb, Pd = shaft.coupling()
    b[o[L.O_SINV]:o[L.O_SINV] + m * m] = Sinv.ravel()
    b[o[L.O_CR]:o[L.O_CR] + m * m] = C.ravel()
    # Φ rows stored transposed-free: row 0 (x) then row 1 (y), each of length m
    b[o[L.O_PHIB]:o[L.O_PHIB] + 2 * m] = Pb.ravel()
    b[o[L.O_PHID]:o[L.O_PHID] + 2 * m] = Pd.ravel()
    b[o[L.O_CB]:o[L.O_CB] + 4] = (Pb @ Sinv @ Pb.T).ravel()
    b[o[L.O_FST]:o[L.O_FST] + m] = shaft.static_force(opts.load.gravity_m_s2, opts.load.disc_n)
    for i, v in enumerate(phys.valve_params(opts.valves.f_scale)):
        wv = v.omega
        Av = np.array([[0.0, 1.0], [-wv * wv, -2 * v.zeta * wv]])
        Bv = np.array([[0.0], [v.gain * wv * wv]])
        Pv, Gv = zoh(Av, Bv, T)
        b[o[L.O_VPHI] + 4 * i:o[L.O_VPHI] + 4 * i + 4] = Pv.ravel()
        b[o[L.O_VGAM] + 2 * i:o[L.O_VGAM] + 2 * i + 2] = Gv.ravel()
        b[o[L.O_VOFF] + i] = v.offset_v
    s = o[L.O_SC]
    b[s + L.SC_OMEGA_RAD] = w
    b[s + L.SC_OMEGA_RPM] = omega_rpm
    b[s + L.SC_PINJ] = p_inj_bar
    b[s + L.SC_PSUP] = p_inj_bar * 1e5 + P_ATM
    b[s + L.SC_PSUP_T] = p_inj_bar * 1e5 + P_ATM
    b[s + L.SC_SLEW] = opts.supply_slew_bar_per_s * 1e5 / fs
    b[s + L.SC_DT] = dt
    b[s + L.SC_NSUB] = opts.substeps
    b[s + L.SC_NEWTON] = opts.newton_iterations
    b[s + L.SC_NEWTON_MAX] = opts.newton_max_iterations
    b[s + L.SC_RES_TOL] = opts.newton_tolerance
    b[s + L.SC_T] = T
    b[s + L.SC_NOISE_E] = opts.noise.e_um
    b[s + L.SC_NOISE_Y] = opts.noise.y_p_v
    b[s + L.SC_SEED] = float(opts.seed)
    b[s + L.SC_UNB] = opts.unbalance_g_mm * 1e-6 * w * w
    b[s + L.SC_UNB_PH] = math.radians(opts.unbalance_phase_deg)
    b[s + L.SC_ALPHA] = al
    b[s + L.SC_SENS] = 1e6
    return b
