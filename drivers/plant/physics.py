"""True physical parameters of the simulated rotor-gas bearing rig vs operating point.

Plain functions, no state: the simulated plant (:mod:`rigd_drivers.sim.driver`) builds its
kernel parameters from them, tests compare identified models against them, and the H∞
design engineer can read the "truth" they are designing for.

Bearing (paper Eq. 4), p = [e_x, e_y] in µm, u = [u_x, u_y] in V (Eq. 1)::

    M p̈ + (D − Ω G) ṗ + K p = B_p u + 1e6 · f_ext

With p in µm every term is a force in µN: M in kg, D and G in N·s/m, K in N/m, B_p in µN/V,
and an external force f_ext in N enters as 1e6·f_ext µN. The identified form of Eq. 6 is then
exactly ``D_id = M⁻¹(D − ΩG)`` (1/s), ``K_id = M⁻¹K`` (1/s²), ``B_id = M⁻¹B_p`` (µm/s²/V).

Operating point: Ω (``omega_rpm``, 0…6000 rpm) and P_I (``p_inj_bar``, 3…7 bar manometric).

* Film stiffness grows with P_I: the Ω = 0 natural frequencies are
  ``f_x0 = 100 + 11·(P_I − 3)`` Hz and ``f_y0 = 1.07·f_x0`` (the disc pre-load stiffens y),
  plus a mild speed stiffening of 3 % at 6 krpm.
* Damping ratio at Ω = 0 follows the paper's measurements: 0.057 at 4 bar, 0.028 at 7 bar,
  log-linear in P_I in between (and extrapolated to 3 bar: 0.072).
* Gyroscopic coupling ``Ω G`` (G antisymmetric) splits the modes into backward/forward whirl
  as Ω grows; a cross-coupled (circulatory) film stiffness ∝ Ω lowers the forward-whirl
  damping slightly; small symmetric cross-couplings in K, D and B_p are always present.
* Actuator gain: static gain K⁻¹B_p ≈ 0.8 µm/V (x) and 0.7 µm/V (y) at every P_I (a ±1 V
  PRBS on r moves u by ±2 V and the shaft by up to ≈ 11 µm at 4 bar, 14 µm at 7 bar).

Valves: valve i (1…4) maps its drive voltage v_i (V) to position y_p,i (V) as a second-order
low pass ``y = g_i ω_i² /(s² + 2 ζ_i ω_i s + ω_i²) · v + offset_i`` (f_i ≈ 400 Hz,
ζ_i ≈ 1.5: two real poles near 150 Hz and 1 kHz). Alone a valve is slow (≈ 150 Hz); under
the suggested PD loop (Kff = 1, Kp = 1.5, Kd = 1e-4 s, τ_d = 1e-4 s) it settles in ≈ 1.2 ms
with no overshoot and a closed-loop bandwidth near 500 Hz: the lumped pair then behaves like
Eq. 8 with κ_a ≈ 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

#: Operating range (paper Sec. 4.3).
OMEGA_RANGE_RPM = (0.0, 6000.0)
P_INJ_RANGE_BAR = (3.0, 7.0)
#: Radial film gap, µm (paper Sec. 2).
GAP_UM = 25.0

# --- bearing constants --------------------------------------------------------------------
MASS_KG = (1.80, 1.80)              # effective modal masses at the disc, x and y
F_X0_3BAR_HZ = 100.0                # f_x at 3 bar, Ω = 0
F_X0_SLOPE_HZ_PER_BAR = 11.0
F_Y_RATIO = 1.07                    # f_y / f_x at Ω = 0
SPEED_STIFFENING = 0.03             # relative stiffness increase at 6 krpm
ZETA_4BAR = 0.057                   # measured open-loop damping ratio at 4 bar (paper Sec. 6)
ZETA_7BAR = 0.028                   # at 7 bar
GYRO_PER_MASS = 0.20                # g / m: gyroscopic coefficient, (N·s/m)/kg = 1/s per rad/s·s
CIRC_AT_6KRPM = 0.010               # circulatory cross stiffness / mean stiffness at 6 krpm
K_CROSS = 0.04                      # symmetric cross stiffness / sqrt(k_x k_y)
D_CROSS = 0.05                      # symmetric cross damping / sqrt(d_x d_y)
STATIC_GAIN_UM_PER_V = (0.8, 0.7)   # diagonal static gain K⁻¹B_p, x and y
B_CROSS = 0.05                      # B_p cross terms relative to the diagonal

# --- valve constants (valves 1..4) -------------------------------------------------------
VALVE_F_HZ = (380.0, 420.0, 400.0, 410.0)   # overdamped: ≈150 Hz amplifier/capacitance pole
VALVE_ZETA = (1.40, 1.60, 1.50, 1.45)       # and ≈1 kHz stack/spool pole
#: Suggested per-valve PD gains (see valve_closed_loop): drive = Kff·r_p + Kp·e + Kd·filtered ė.
PD_KFF = 1.0           # V/V feed-forward of the reference (keeps the drive near mid-range)
PD_KP = 1.5            # V/V
PD_KD = 1.0e-4         # V·s/V
PD_TAU_D = 1.0e-4      # s, first-order derivative filter
VALVE_GAIN = (1.00, 0.97, 1.03, 0.99)
VALVE_OFFSET_V = (0.05, -0.03, 0.02, -0.04)


@dataclass(frozen=True)
class BearingMatrices:
    """Matrices of Eq. 4 and the identified form of Eq. 6 at one operating point.

    Attributes
    ----------
    M, D, G, K : ndarray (2, 2)
        Mass (kg), damping (N·s/m), gyroscopic (N·s/m per rad/s of Ω... i.e. kg), stiffness (N/m).
    B_p : ndarray (2, 2)
        Actuator force per lumped valve position, µN/V (p is in µm).
    D_id, K_id, B_id : ndarray (2, 2)
        Eq. 6: ``M⁻¹(D − ΩG)`` (1/s), ``M⁻¹K`` (1/s²), ``M⁻¹B_p`` (µm/s²/V).
    F_id : ndarray (2, 2)
        Acceleration per external force, µm/s² per N: ``1e6·M⁻¹``.
    omega_rad_s : float
        Ω in rad/s.
    """

    M: np.ndarray
    D: np.ndarray
    G: np.ndarray
    K: np.ndarray
    B_p: np.ndarray
    D_id: np.ndarray
    K_id: np.ndarray
    B_id: np.ndarray
    F_id: np.ndarray
    omega_rad_s: float


def check_operating_point(omega_rpm: float, p_inj_bar: float) -> None:
    """Raise ``ValueError`` when (Ω, P_I) is outside the documented range."""
    lo, hi = OMEGA_RANGE_RPM
    if not (np.isfinite(omega_rpm) and lo <= omega_rpm <= hi):
        raise ValueError(f"omega_rpm must be in [{lo:g}, {hi:g}] rpm (got {omega_rpm!r})")
    lo, hi = P_INJ_RANGE_BAR
    if not (np.isfinite(p_inj_bar) and lo <= p_inj_bar <= hi):
        raise ValueError(f"p_inj_bar must be in [{lo:g}, {hi:g}] bar (got {p_inj_bar!r})")


def zeta_static(p_inj_bar: float) -> float:
    """Open-loop damping ratio at Ω = 0 (log-linear through the paper's 4 and 7 bar values)."""
    return ZETA_4BAR * (ZETA_7BAR / ZETA_4BAR) ** ((p_inj_bar - 4.0) / 3.0)


@njit(cache=True, nogil=True)
def bearing_core(omega_rpm: float, p_inj_bar: float):
    """M, D, G, K (kg, N·s/m, kg, N/m) and B_p (µN/V) of Eq. 4 at (Ω rpm, P_I bar), each
    float64 (2, 2); compiled, runs without the GIL (no range check: see
    :func:`bearing_matrices`). The one place the bearing's physics is written."""
    s = omega_rpm / OMEGA_RANGE_RPM[1]                     # 0..1
    m0, m1 = MASS_KG
    fx0 = F_X0_3BAR_HZ + F_X0_SLOPE_HZ_PER_BAR * (p_inj_bar - 3.0)
    w0, w1 = 2 * np.pi * fx0, 2 * np.pi * (F_Y_RATIO * fx0)
    k0 = m0 * w0 ** 2 * (1.0 + SPEED_STIFFENING * s)
    k1 = m1 * w1 ** 2 * (1.0 + SPEED_STIFFENING * s)
    zeta = ZETA_4BAR * (ZETA_7BAR / ZETA_4BAR) ** ((p_inj_bar - 4.0) / 3.0)
    c0 = 2.0 * zeta * m0 * w0
    c1 = 2.0 * zeta * m1 * w1
    kxy = K_CROSS * np.sqrt(k0 * k1)
    kc = CIRC_AT_6KRPM * s * ((k0 + k1) / 2.0)
    dxy = D_CROSS * np.sqrt(c0 * c1)
    g = GYRO_PER_MASS * ((m0 + m1) / 2.0)
    # B_p: static gain K⁻¹B_p ≈ diag(STATIC_GAIN) at Ω = 0 (p in µm -> forces in µN).
    b0 = STATIC_GAIN_UM_PER_V[0] * (m0 * w0 ** 2)
    b1 = STATIC_GAIN_UM_PER_V[1] * (m1 * w1 ** 2)
    M = np.array([[m0, 0.0], [0.0, m1]])
    D = np.array([[c0, dxy], [dxy, c1]])
    G = np.array([[0.0, g], [-g, 0.0]])
    K = np.array([[k0, kxy + kc], [kxy - kc, k1]])
    B_p = np.array([[b0, B_CROSS * b0], [-B_CROSS * b1, b1]])
    return M, D, G, K, B_p


def bearing_matrices(omega_rpm: float, p_inj_bar: float) -> BearingMatrices:
    """True bearing matrices of Eq. 4 (and Eq. 6) at speed Ω (rpm) and pressure P_I (bar)."""
    check_operating_point(omega_rpm, p_inj_bar)
    w_rad = omega_rpm * 2.0 * np.pi / 60.0
    M, D, G, K, B_p = bearing_core(float(omega_rpm), float(p_inj_bar))
    Minv = np.diag(1.0 / np.diag(M))
    return BearingMatrices(M=M, D=D, G=G, K=K, B_p=B_p,
                           D_id=Minv @ (D - w_rad * G), K_id=Minv @ K, B_id=Minv @ B_p,
                           F_id=1e6 * Minv, omega_rad_s=w_rad)


def bearing_state_matrices(omega_rpm: float, p_inj_bar: float) -> tuple[np.ndarray, np.ndarray,
                                                                         np.ndarray]:
    """Continuous (A, B_u, B_f) of Eq. 5–6, states x = [e_x, e_y, ė_x, ė_y] (µm, µm/s).

    ``B_u`` maps u (V), ``B_f`` maps an external force (N).
    """
    bm = bearing_matrices(omega_rpm, p_inj_bar)
    A = np.zeros((4, 4))
    A[0:2, 2:4] = np.eye(2)
    A[2:4, 0:2] = -bm.K_id
    A[2:4, 2:4] = -bm.D_id
    Bu = np.zeros((4, 2))
    Bu[2:4] = bm.B_id
    Bf = np.zeros((4, 2))
    Bf[2:4] = bm.F_id
    return A, Bu, Bf


def bearing_modes(omega_rpm: float, p_inj_bar: float) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies (Hz) and damping ratios of the two bearing modes, sorted by frequency.

    From the eigenvalues λ of A (Eq. 6): ``f = |λ|/2π``, ``ζ = −Re λ/|λ|``. At Ω = 0 the first
    mode is the (mostly) horizontal one, the second the vertical one.
    """
    A, _, _ = bearing_state_matrices(omega_rpm, p_inj_bar)
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    wn = np.abs(lam)
    order = np.argsort(wn)
    return wn[order] / (2 * np.pi), (-lam.real / wn)[order]


def bearing_ss(omega_rpm: float, p_inj_bar: float, *, force_inputs: bool = False):
    """python-control ``StateSpace`` of the bearing, u (V) → p (µm) (Eq. 5–6).

    With ``force_inputs=True`` two more inputs take the external force f_x, f_y (N).
    """
    import control

    A, Bu, Bf = bearing_state_matrices(omega_rpm, p_inj_bar)
    B = np.hstack([Bu, Bf]) if force_inputs else Bu
    C = np.hstack([np.eye(2), np.zeros((2, 2))])
    names_in = ["u_x", "u_y"] + (["f_x", "f_y"] if force_inputs else [])
    return control.ss(A, B, C, np.zeros((2, B.shape[1])), inputs=names_in,
                      outputs=["e_x", "e_y"], states=["e_x", "e_y", "de_x", "de_y"])


@dataclass(frozen=True)
class ValveParams:
    """One piezo valve: ``y_p = gain·ω²/(s² + 2ζωs + ω²)·v + offset`` (V → V)."""

    f_hz: float
    zeta: float
    gain: float
    offset_v: float

    @property
    def omega(self) -> float:
        return 2 * np.pi * self.f_hz


def valve_params(scale_f: float = 1.0) -> list[ValveParams]:
    """True parameters of valves 1…4 (independent of the operating point).

    ``scale_f`` scales every valve's natural frequency (the sim option ``valves.f_scale``).
    """
    return [ValveParams(f * scale_f, z, g, o) for f, z, g, o in
            zip(VALVE_F_HZ, VALVE_ZETA, VALVE_GAIN, VALVE_OFFSET_V)]


def valve_tf(valve: ValveParams):
    """python-control transfer function drive v (V) → position y_p (V), offset excluded."""
    import control

    w = valve.omega
    return control.tf([valve.gain * w * w], [1.0, 2 * valve.zeta * w, w * w])


def valve_closed_loop(valve: ValveParams, kp: float = PD_KP, kd: float = PD_KD,
                      tau_d: float = PD_TAU_D, fs: float = 5000.0, kff: float = PD_KFF):
    """Discrete closed-loop transfer function r_p,i → y_p,i of one valve under a PD loop.

    The valve is discretised exactly (ZOH on the drive, which the plant holds over a period);
    the PD acts on the error e = r − y with a backward-Euler filtered derivative
    ``d_k = (τ_d·d_{k-1} + (e_k − e_{k-1}))/(τ_d + T)``, drive ``Kff·r_k + Kp·e_k + Kd·d_k``
    (the loop's ``rigd.loop.cycle.pd_step``), no clamp. The static gain is
    ``g·(Kff + Kp)/(1 + Kp·g)`` (no integral action: Eq. 8's κ_a).

    Returns
    -------
    control.TransferFunction
        Discrete, ``dt = 1/fs``.
    """
    import control

    T = 1.0 / fs
    G = control.c2d(valve_tf(valve), T, method="zoh")
    z = control.tf([1.0, 0.0], [1.0], T)
    C = kp + kd * (1 - z ** -1) / (tau_d * (1 - z ** -1) + T)
    return control.minreal((kff + C) * G / (1 + C * G), verbose=False)


def lumped_actuator_tf(axis: str, kp: float = PD_KP, kd: float = PD_KD,
                       tau_d: float = PD_TAU_D, fs: float = 5000.0, scale_f: float = 1.0,
                       kff: float = PD_KFF):
    """Discrete r_j → u_j of one lumped valve pair (Eq. 1 and Eq. 8), j = ``"x"`` or ``"y"``.

    u_x = y_p2 − y_p4 with r_p2 = r0 + r_x, r_p4 = r0 − r_x, hence H_x = H_2 + H_4
    (H_y = H_1 + H_3). Static gain ≈ 2 with the suggested gains (≈ 1.2 with Kff = 0).
    """
    v = valve_params(scale_f)
    i, j = {"x": (1, 3), "y": (0, 2)}[axis]
    return (valve_closed_loop(v[i], kp, kd, tau_d, fs, kff)
            + valve_closed_loop(v[j], kp, kd, tau_d, fs, kff))


def step_metrics(tf, n: int = 200) -> dict[str, float]:
    """Overshoot (fraction), 2 % settling time (s) and −3 dB bandwidth (Hz) of a discrete TF."""
    import control

    T = tf.dt
    t, y = control.step_response(tf, T=np.arange(n) * T)
    y = np.asarray(y).ravel()
    fin = y[-1]
    out = np.abs(y - fin) > 0.02 * abs(fin)
    ts = (np.nonzero(out)[0].max() + 1) * T if out.any() else 0.0
    f = np.linspace(1.0, 0.5 / T * 0.99, 2000)
    mag = np.abs(tf(np.exp(2j * np.pi * f * T))) / abs(fin)
    below = np.nonzero(mag < 1 / np.sqrt(2))[0]
    return {"overshoot": float(max(0.0, (y.max() - fin) / abs(fin))), "settling_s": float(ts),
            "bandwidth_hz": float(f[below[0]]) if below.size else float("nan"),
            "static_gain": float(fin)}
