"""Records generated in the tests from published benchmark systems (no shipped data, no fits).

Each generator integrates the system's equations itself (RK4 with sub-steps on the analytic
excitation), adds measurement noise and returns a generic :class:`rigd.data.record.Record`
(``inputs``/``outputs`` in its metadata, no ``rigd_version``: data the project did not make),
in the benchmark's own units and rate:

* :func:`bouc_wen` — single-DOF oscillator with a Bouc–Wen hysteretic restoring force, the
  *Hysteretic benchmark with a dynamic nonlinearity* (Noël & Schoukens, 2016):
  m ÿ + c ẏ + k y + z = u,  ż = α ẏ − β (γ |ẏ| |z|^(ν−1) z + δ ẏ |z|^ν), ν = 1,
  m = 2 kg, c = 10 N s/m, k = 5·10⁴ N/m, α = 5·10⁴ N/m, β = 10³ m⁻¹, γ = 0.8, δ = −1.1;
  750 Hz, random-phase multisine 5–150 Hz; y in metres, u in newtons. ``variant`` scales
  (β, γ, δ) within the ranges the benchmark's parameter studies use.
* :func:`three_mode` — a 3-mass spring–damper chain (the classic flexible-structure
  benchmark: three discs on a torsional shaft / three carts, force on the first mass,
  displacement of the last, non-collocated), Rayleigh damping; 200 Hz; mm and N.
* :func:`tank_overflow` — the *Cascaded tanks* benchmark (Schoukens, Mattsson, Wigren &
  Noël, 2016): ẋ₁ = −k₁√x₁ + k₄ u, ẋ₂ = k₂√x₁ − k₃√x₂, the upper tank overflows when x₁
  reaches its top (x₁ saturates at 10 V, the excess water is lost); output x₂ (V); Ts = 4 s.
* :func:`duffing` — a Duffing oscillator (the Silverbox's equation), ÿ + 2ζω ẏ + ω² y +
  k₃ y³ = b u; 1 kHz; mm and V.
"""

from __future__ import annotations

import numba
import numpy as np

from rigd.data.record import Record


def multisine(n: int, fs: float, f_lo: float, f_hi: float, rms: float,
              rng: np.random.Generator, sub: int = 1) -> np.ndarray:
    """Random-phase multisine (flat amplitude on the lines f_lo..f_hi of an n-sample period),
    sampled ``sub`` times per sample (n·sub values)."""
    k = np.arange(max(1, int(np.ceil(f_lo * n / fs))), int(np.floor(f_hi * n / fs)) + 1)
    ph = rng.uniform(0, 2 * np.pi, k.size)
    t = np.arange(n * sub) / (fs * sub)
    x = np.zeros(n * sub)
    for kk, p in zip(k, ph):
        x += np.cos(2 * np.pi * kk * fs / n * t + p)
    return x * rms / np.sqrt(np.mean(x ** 2))


def steps(n: int, rng: np.random.Generator, levels: np.ndarray, hold: tuple[int, int],
          sub: int = 1) -> np.ndarray:
    """Random multi-level steps held ``hold`` samples (n·sub values, held between samples)."""
    out = np.empty(n)
    k = 0
    while k < n:
        h = int(rng.integers(*hold))
        out[k:k + h] = rng.choice(levels)
        k += h
    return np.repeat(out, sub)


def _record(u, y, fs, uname, yname, units, rng, snr_db):
    y = y + 10 ** (-snr_db / 20) * np.std(y) * rng.standard_normal(y.shape)
    meta = {"inputs": [uname], "outputs": [yname], "units": units}
    return Record({"t": np.arange(len(u)) / fs, uname: np.asarray(u, float),
                   yname: np.asarray(y, float)}, fs, meta, source="<generated>")


# --------------------------------------------------------------------------------------
# Bouc–Wen hysteretic oscillator (Noël & Schoukens 2016)
# --------------------------------------------------------------------------------------
BW_NOMINAL = dict(m=2.0, c=10.0, k=5e4, alpha=5e4, beta=1e3, gamma=0.8, delta=-1.1)
BW_VARIANTS = [dict(), dict(beta=1.5e3), dict(gamma=0.9, delta=-1.0), dict(beta=7e2)]


@numba.njit(cache=True)
def _bw_run(u, h, m, c, k, alpha, beta, gamma, delta):
    n = u.shape[0]
    y = np.empty(n)
    x = np.zeros(3)  # y, ẏ, z
    for i in range(n):
        y[i] = x[0]
        ui = u[i]
        k1 = np.empty(3)
        xs = x.copy()
        acc = np.zeros(3)
        for stage in range(4):
            if stage == 0:
                xs[:] = x
            elif stage < 3:
                xs[:] = x + 0.5 * h * k1
            else:
                xs[:] = x + h * k1
            v, z = xs[1], xs[2]
            k1[0] = v
            k1[1] = (ui - c * v - k * xs[0] - z) / m
            k1[2] = alpha * v - beta * (gamma * abs(v) * z + delta * v * abs(z))
            acc += k1 * (1.0 if stage in (0, 3) else 2.0)
        x = x + h / 6.0 * acc
    return y


def bouc_wen(seed: int = 0, variant: int = 0, n: int = 6000, rms: float = 50.0,
             snr_db: float = 40.0, sub: int = 20) -> Record:
    """The Bouc–Wen benchmark at 750 Hz: force (N) -> displacement (m)."""
    rng = np.random.default_rng(seed)
    p = dict(BW_NOMINAL, **BW_VARIANTS[variant % len(BW_VARIANTS)])
    fs = 750.0
    uf = multisine(n, fs, 5.0, 150.0, rms, rng, sub)
    # RK4 on the fine grid (input held over each fine step); the recorded u is the sampled one
    yf = _bw_run(uf, 1.0 / (fs * sub), p["m"], p["c"], p["k"], p["alpha"], p["beta"],
                 p["gamma"], p["delta"])
    return _record(uf[::sub], yf[::sub], fs, "force", "disp", {"force": "N", "disp": "m"},
                   rng, snr_db)


def bouc_wen_linear(seed: int = 0, n: int = 6000, rms: float = 50.0) -> Record:
    """The same oscillator with the hysteretic force replaced by its small-amplitude
    stiffness α y (β = 0): the no-effect control."""
    rng = np.random.default_rng(seed)
    fs, sub = 750.0, 20
    uf = multisine(n, fs, 5.0, 150.0, rms, rng, sub)
    p = BW_NOMINAL
    yf = _bw_run(uf, 1.0 / (fs * sub), p["m"], p["c"], p["k"], p["alpha"], 0.0, 0.0, 0.0)
    return _record(uf[::sub], yf[::sub], fs, "force", "disp", {"force": "N", "disp": "m"},
                   rng, 40.0)


# --------------------------------------------------------------------------------------
# 3-mass chain (flexible structure, three modes)
# --------------------------------------------------------------------------------------
def three_mode_matrices(k: float = 4e3, m: float = 1.0):
    """(M⁻¹K, M⁻¹D, M⁻¹b) of the chain wall–k–m1–k–m2–k–m3 (free end), Rayleigh damping
    D = 0.5·M + 2e-4·K (ζ ≈ 1–3 % on the three modes)."""
    K = k * np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]) / m
    D = 0.5 * np.eye(3) + 2e-4 * K
    b = np.array([1.0, 0.0, 0.0]) / m
    return K, D, b


def three_mode_frequencies() -> np.ndarray:
    K, _, _ = three_mode_matrices()
    return np.sort(np.sqrt(np.linalg.eigvalsh(K))) / (2 * np.pi)


def three_mode(seed: int = 0, n: int = 8000, snr_db: float = 40.0) -> Record:
    """Force on mass 1 (N) -> displacement of mass 3 (mm), 200 Hz, multisine 0.5–40 Hz."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    fs = 200.0
    K, D, b = three_mode_matrices()
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-K, -D]])
    B = np.concatenate([np.zeros(3), b])[:, None]
    C = np.zeros((1, 6))
    C[0, 2] = 1e3  # m -> mm
    sub = 10
    uf = multisine(n, fs, 0.5, 40.0, 20.0, rng, sub)
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, np.zeros((1, 1))), 1 / (fs * sub))
    _, yf, _ = signal.dlsim((Ad, Bd, Cd, Dd, 1 / (fs * sub)), uf)
    return _record(uf[::sub], yf[::sub, 0], fs, "F", "x3", {"F": "N", "x3": "mm"}, rng,
                   snr_db)


# --------------------------------------------------------------------------------------
# cascaded tanks with overflow (Schoukens et al. 2016)
# --------------------------------------------------------------------------------------
TANK = dict(k1=0.06, k2=0.055, k3=0.05, k4=0.045, top=10.0)


@numba.njit(cache=True)
def _tank_run(u, h, k1, k2, k3, k4, top):
    n = u.shape[0]
    y = np.empty(n)
    x1, x2 = 1.0, 1.0
    for i in range(n):
        y[i] = x2
        # forward Euler on a fine grid; the upper tank overflows at its top
        x1 = min(top, max(0.0, x1 + h * (-k1 * np.sqrt(x1) + k4 * u[i])))
        x2 = min(top, max(0.0, x2 + h * (k2 * np.sqrt(x1) - k3 * np.sqrt(x2))))
    return y


def tank_overflow(seed: int = 0, n: int = 3000, snr_db: float = 40.0) -> Record:
    """Pump voltage (V) -> lower-tank level (V), Ts = 4 s; steps 1..9 V held 15–60 samples,
    large enough that the upper tank overflows at the top levels."""
    rng = np.random.default_rng(seed)
    fs, sub = 0.25, 40
    uf = steps(n, rng, np.linspace(1.0, 9.0, 9), (15, 60), sub)
    p = TANK
    yf = _tank_run(uf, 1.0 / (fs * sub), p["k1"], p["k2"], p["k3"], p["k4"], p["top"])
    return _record(uf[::sub], yf[::sub], fs, "pump", "level2", {"pump": "V", "level2": "V"},
                   rng, snr_db)


# --------------------------------------------------------------------------------------
# Duffing oscillator
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _duffing_run(u, h, w, zeta, k3, b):
    n = u.shape[0]
    y = np.empty(n)
    p, v = 0.0, 0.0
    for i in range(n):
        y[i] = p
        ui = u[i]
        a1 = b * ui - 2 * zeta * w * v - w * w * p - k3 * p ** 3
        p2, v2 = p + 0.5 * h * v, v + 0.5 * h * a1
        a2 = b * ui - 2 * zeta * w * v2 - w * w * p2 - k3 * p2 ** 3
        p3, v3 = p + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = b * ui - 2 * zeta * w * v3 - w * w * p3 - k3 * p3 ** 3
        p4, v4 = p + h * v3, v + h * a3
        a4 = b * ui - 2 * zeta * w * v4 - w * w * p4 - k3 * p4 ** 3
        p += h / 6 * (v + 2 * v2 + 2 * v3 + v4)
        v += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    return y


def duffing(seed: int = 0, n: int = 6000, strength: float = 0.4,
            snr_db: float = 40.0) -> Record:
    """Voltage (V) -> displacement (mm), 1 kHz, f_n = 60 Hz, ζ = 0.05, multisine 2–150 Hz;
    the cubic force is ``strength`` times the linear one at the largest linear response."""
    rng = np.random.default_rng(seed)
    fs, sub = 1000.0, 10
    w, zeta, b = 2 * np.pi * 60.0, 0.05, (2 * np.pi * 60.0) ** 2 * 0.02
    uf = multisine(n, fs, 2.0, 150.0, 1.0, rng, sub)
    ylin = _duffing_run(uf, 1 / (fs * sub), w, zeta, 0.0, b)
    pmax = np.percentile(np.abs(ylin), 99.5)
    k3 = strength * w * w / pmax ** 2
    yf = _duffing_run(uf, 1 / (fs * sub), w, zeta, k3, b)
    return _record(uf[::sub], yf[::sub], fs, "V", "y_mm", {"V": "V", "y_mm": "mm"}, rng,
                   snr_db)
