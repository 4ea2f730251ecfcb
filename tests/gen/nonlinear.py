"""Nonlinear systems: block-oriented (Hammerstein, Wiener) and a Bouc–Wen oscillator.

* :func:`hammerstein` — static input curve v = f(u), then second-order linear dynamics;
* :func:`wiener` — linear dynamics x = G u, then a static output curve y = g(x);
* :func:`wiener_two_outputs` — one input, two first-order lags of different time
  constants, each read through its own static curve (a MIMO Wiener, per-output curves);
* :func:`state_dependent_lag` — a first-order plant whose time constant depends on its own
  state (Arrhenius-like: faster when hot), not block-oriented;
* :func:`radiant_furnace` — a heating element and its load losing heat by radiation
  (σ T⁴ of each state fed back into its own balance: a Lur'e form of the outputs);
* :func:`bouc_wen` — m ÿ + c ẏ + k y + z = u with ż = α ẏ − β(γ|ẏ| z + δ ẏ |z|)
  (hysteresis in the restoring force), RK4 on a grid 20× finer than the record.
"""

from __future__ import annotations

import numba
import numpy as np

from tests.gen.linear import simulate_ct
from tests.gen.record import Generated, add_noise
from tests.gen.signals import held_steps, multisine

#: static curves by name: f(u) on a normalised argument
CURVES = {
    "cubic": lambda x: x + 0.6 * x ** 3,
    "saturation": lambda x: np.tanh(1.5 * x) / 1.5,
    "deadzone": lambda x: np.sign(x) * np.maximum(np.abs(x) - 0.3, 0.0),
    "square": lambda x: x + 0.5 * x ** 2,
}


def _lin2(f_hz: float, zeta: float):
    w = 2 * np.pi * f_hz
    return (np.array([[0, 1], [-w * w, -2 * zeta * w]]), np.array([[0], [w * w]]),
            np.array([[1.0, 0.0]]), np.zeros((1, 1)))


def hammerstein(curve: str = "cubic", f_hz: float = 0.8, zeta: float = 0.4, fs: float = 20.0,
                n: int = 6000, snr_db: float = 40.0, seed: int = 0, scale: float = 2.0
                ) -> Generated:
    """Valve opening (%) → flow (l/min): v = scale·f(u/scale) (``curve``), then a
    second-order lag (f_hz, ζ); held random levels."""
    rng = np.random.default_rng(seed)
    u = held_steps(n, rng, (int(fs * 0.5 / f_hz), int(fs * 3 / f_hz)), amp=scale)
    v = scale * CURVES[curve](u / scale)
    clean = simulate_ct(*_lin2(f_hz, zeta), v, fs)
    truth = dict(kind="hammerstein", nonlinearity=dict(site="input", curve=curve,
                 scale=scale), order=2, modes=[(f_hz, zeta)], delays=[0.0],
                 integrator=False, closed_loop=False)
    return Generated(u, add_noise(clean, snr_db, rng), fs, ["valve"], ["flow"],
                     {"valve": "%", "flow": "l/min"}, truth, clean)


def wiener(curve: str = "saturation", f_hz: float = 0.5, zeta: float = 0.5, fs: float = 10.0,
           n: int = 5000, snr_db: float = 40.0, seed: int = 0, scale: float = 1.0
           ) -> Generated:
    """Heater voltage (V) → sensor reading (mV): x = linear second-order response, then
    y = scale·g(x/scale) (``curve``)."""
    rng = np.random.default_rng(seed)
    u = held_steps(n, rng, (int(fs * 0.5 / f_hz), int(fs * 3 / f_hz)), amp=1.5 * scale)
    x = simulate_ct(*_lin2(f_hz, zeta), u, fs)
    clean = scale * CURVES[curve](x / scale)
    truth = dict(kind="wiener", nonlinearity=dict(site="output", curve=curve, scale=scale),
                 order=2, modes=[(f_hz, zeta)], delays=[0.0], integrator=False,
                 closed_loop=False)
    return Generated(u, add_noise(clean, snr_db, rng), fs, ["voltage"], ["reading"],
                     {"voltage": "V", "reading": "mV"}, truth, clean)


def wiener_two_outputs(curves=("saturation", "square"), taus_s=(30.0, 80.0),
                       fs: float = 0.5, n: int = 3000, snr_db: float = 40.0, seed: int = 0,
                       scale: float = 2.0) -> Generated:
    """Inlet valve (%) → outlet temperature (K) and pressure (kPa): two first-order lags
    (time constants ``taus_s``, s; gains 1) of the same input, each output read through its
    own curve ``scale·g(x/scale)`` (``curves``); levels held 0.3–3 of the slower lag."""
    rng = np.random.default_rng(seed)
    slow = max(taus_s)
    u = 40.0 + held_steps(n, rng, (max(1, int(0.3 * slow * fs)), int(3 * slow * fs)),
                          amp=1.5 * scale)[:, 0]
    x = simulate_ct(np.diag([-1.0 / t for t in taus_s]),
                    np.array([[1.0 / t] for t in taus_s]), np.eye(2), np.zeros((2, 1)),
                    u - 40.0, fs)
    clean = np.column_stack([scale * CURVES[c](x[:, i] / scale) for i, c in enumerate(curves)])
    clean = clean + np.array([350.0, 120.0])
    truth = dict(kind="wiener", nonlinearity=dict(site="output", curve=list(curves),
                 scale=scale), order=2, time_constants=list(taus_s), delays=[0.0],
                 integrator=False, closed_loop=False)
    return Generated(u[:, None], add_noise(clean, snr_db, rng), fs, ["valve"],
                     ["temperature", "pressure"],
                     {"valve": "%", "temperature": "K", "pressure": "kPa"}, truth, clean)


def state_dependent_lag(tau_s: float = 20.0, activation: float = 1.2, fs: float = 2.0,
                        n: int = 4000, snr_db: float = 40.0, seed: int = 0,
                        sub: int = 20) -> Generated:
    """Heating power (kW) → temperature rise (K): τ(x) ẋ = −x + u with τ(x) =
    τ₀·exp(−activation·x/x_ref) (faster when hot, x_ref the steady state of the mean
    input), Euler on a grid ``sub`` times finer; levels held 0.2–2 τ₀."""
    rng = np.random.default_rng(seed)
    u = 1.0 + held_steps(n, rng, (max(1, int(0.2 * tau_s * fs)), int(2 * tau_s * fs)),
                         amp=0.8)[:, 0]
    h, x, y = 1.0 / (fs * sub), 1.0, np.empty(n)
    for i in range(n):
        y[i] = x
        for _ in range(sub):
            x += h * (u[i] - x) / (tau_s * np.exp(-activation * (x - 1.0)))
    clean = y[:, None]
    truth = dict(kind="state_dependent_lag", nonlinearity=dict(site="state",
                 effect="state-dependent time constant"), order=1, delays=[0.0],
                 integrator=False, closed_loop=False)
    return Generated(u[:, None], add_noise(clean, snr_db, rng), fs, ["power"], ["rise"],
                     {"power": "kW", "rise": "K"}, truth, clean)


def radiant_furnace(fs: float = 0.2, n: int = 4000, snr_db: float = 40.0, seed: int = 0,
                    sub: int = 20) -> Generated:
    """Heater power (kW) → element and load temperatures (°C): two heat balances,

        C_e Ṫ_e = P − k (T_e − T_l) − a_e σ (T_e⁴ − T_a⁴),
        C_l Ṫ_l = k (T_e − T_l) − a_l σ (T_l⁴ − T_a⁴),

    (kelvin inside, T_a = 293 K), radiation the larger loss at the top of the range: the
    time constants fall as the furnace heats. Euler on a grid ``sub`` times finer; power
    levels 0.5–6 kW held 0.05–0.5 of the load's time constant."""
    rng = np.random.default_rng(seed)
    sigma, ta = 5.67e-8, 293.0
    ce, cl, k, ae, al = 2.0e3, 2.0e4, 20.0, 0.05, 0.1
    p = 3.25 + held_steps(n, rng, (max(1, int(40 * fs)), int(400 * fs)), amp=2.75)[:, 0]
    h = 1.0 / (fs * sub)
    te, tl = 900.0, 700.0
    y = np.empty((n, 2))
    for i in range(n):
        y[i] = te - 273.15, tl - 273.15
        for _ in range(sub):
            q = k * (te - tl)
            te += h * (1e3 * p[i] - q - ae * sigma * (te ** 4 - ta ** 4)) / ce
            tl += h * (q - al * sigma * (tl ** 4 - ta ** 4)) / cl
    truth = dict(kind="radiant_furnace", nonlinearity=dict(site="state",
                 effect="radiative losses σT⁴ of each state"), order=2, delays=[0.0, 0.0],
                 integrator=False, closed_loop=False)
    return Generated(p[:, None], add_noise(y, snr_db, rng), fs, ["power"],
                     ["element", "load"], {"power": "kW", "element": "°C", "load": "°C"},
                     truth, y)


@numba.njit(cache=True)
def _bw_rk4(u, h, sub, m, c, k, alpha, beta, gamma, delta):  # pragma: no cover - compiled
    n = u.shape[0]
    y = np.empty(n)
    x = np.zeros(3)
    kk = np.empty((4, 3))
    for i in range(n):
        y[i] = x[0]
        for _ in range(sub):
            for s in range(4):
                w = 0.0 if s == 0 else (0.5 if s < 3 else 1.0)
                p = x[0] + w * h * (kk[s - 1, 0] if s else 0.0)
                v = x[1] + w * h * (kk[s - 1, 1] if s else 0.0)
                z = x[2] + w * h * (kk[s - 1, 2] if s else 0.0)
                kk[s, 0] = v
                kk[s, 1] = (u[i] - c * v - k * p - z) / m
                kk[s, 2] = alpha * v - beta * (gamma * abs(v) * z + delta * v * abs(z))
            for j in range(3):
                x[j] += h / 6.0 * (kk[0, j] + 2 * kk[1, j] + 2 * kk[2, j] + kk[3, j])
    return y


#: Bouc–Wen parameters (SI) of :func:`bouc_wen` (a 1 kg, 16 Hz oscillator, strong hysteresis)
BW = dict(m=1.0, c=4.0, k=1.0e4, alpha=1.0e4, beta=400.0, gamma=0.8, delta=-1.1)


def bouc_wen(n: int = 8000, fs: float = 500.0, rms: float = 20.0, snr_db: float = 40.0,
             seed: int = 0, sub: int = 20, **params) -> Generated:
    """Force (N) → displacement (mm) of a Bouc–Wen oscillator (module docstring; ``params``
    override :data:`BW`); multisine 2–60 Hz, input held over each sample."""
    rng = np.random.default_rng(seed)
    p = dict(BW, **params)
    u = multisine(n, fs, 2.0, 60.0, rms, rng)[:, 0]
    y = 1e3 * _bw_rk4(u, 1.0 / (fs * sub), sub, p["m"], p["c"], p["k"], p["alpha"],
                      p["beta"], p["gamma"], p["delta"])
    truth = dict(kind="bouc_wen", nonlinearity=dict(site="state", effect="hysteresis"),
                 params=p, delays=[0.0], integrator=False, closed_loop=False)
    clean = y[:, None]
    return Generated(u[:, None], add_noise(clean, snr_db, rng), fs, ["force"], ["disp"],
                     {"force": "N", "disp": "mm"}, truth, clean)
