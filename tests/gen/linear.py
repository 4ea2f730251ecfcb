"""Linear plants (continuous time, simulated exactly through a zero-order hold).

* :func:`thermal` — first-order heater with a transport delay (°C from %, slow rate);
* :func:`integrator_loop` — an integrating plant k/(s(τs + 1)) under P or PI feedback,
  recorded in closed loop (the plant input is the controller's output);
* :func:`structure` — a mechanical structure in modal form, any number of inputs, outputs and
  modes; :func:`structure_2in_6modes` and :func:`structure_2in_3modes` the two standard ones.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from tests.gen.record import Generated, add_noise
from tests.gen.signals import held_steps, multisine


def simulate_ct(A, B, C, D, u: np.ndarray, fs: float, delays=None, sub: int = 16
                ) -> np.ndarray:
    """Output (n, ny) of the continuous system (A, B, C, D) for inputs ``u`` (n, nu) held
    over each sample (ZOH), each input delayed by ``delays`` (samples, may be fractional:
    then simulated on a grid ``sub`` times finer), from rest."""
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (A, B, C, D))
    u = np.asarray(u, float).reshape(len(u), -1)
    n, nu = u.shape
    delays = np.zeros(nu) if delays is None else np.asarray(delays, float).reshape(nu)
    if np.allclose(delays, np.round(delays)):
        sub = 1
    uf = np.repeat(u, sub, axis=0)
    shifted = np.zeros_like(uf)
    for j in range(nu):
        d = int(round(delays[j] * sub))
        shifted[d:, j] = uf[:len(uf) - d, j]
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, D), 1.0 / (fs * sub), "zoh")
    _, y, _ = signal.dlsim((Ad, Bd, Cd, Dd, 1.0 / (fs * sub)), shifted)
    return np.asarray(y).reshape(len(uf), -1)[::sub]


def thermal(delay: float = 3.0, tau_s: float = 40.0, gain: float = 0.6, fs: float = 1.0,
            n: int = 3000, snr_db: float = 35.0, seed: int = 0, ambient: float = 20.0
            ) -> Generated:
    """A heater: power (%, 0–100) → temperature (°C) = ambient + gain/(τs + 1)·power,
    delayed ``delay`` samples; power steps held 0.5–2 τ."""
    rng = np.random.default_rng(seed)
    hold = (max(1, int(0.5 * tau_s * fs)), max(2, int(2 * tau_s * fs)))
    u = 50.0 + held_steps(n, rng, hold, amp=45.0)
    y0 = simulate_ct([[-1 / tau_s]], [[gain / tau_s]], [[1.0]], [[0.0]], u - 50.0, fs,
                     [delay])
    clean = ambient + gain * 50.0 + y0
    truth = dict(kind="thermal", delays=[float(delay)], order=1, time_constants=[tau_s],
                 poles=[-1 / tau_s], dc_gain=[[gain]], integrator=False, closed_loop=False)
    return Generated(u, add_noise(clean, snr_db, rng), fs, ["power"], ["temperature"],
                     {"power": "%", "temperature": "degC"}, truth, clean)


def integrator_loop(controller: str = "PI", k: float = 2.0, tau_s: float = 0.05,
                    kp: float = 3.0, ti_s: float = 2.0, fs: float = 50.0, n: int = 6000,
                    snr_db: float = 40.0, seed: int = 0, disturbance: float = 0.05
                    ) -> Generated:
    """An integrating plant y = k/(s(τs + 1)) (u in V, y in m) under feedback
    u = kp·(e + ∫e/ti) (``"PI"``) or kp·e (``"P"``), e = r − y_measured; the reference r
    steps (held 1–4 s); an input disturbance (white, ``disturbance`` V rms) and measurement
    noise act inside the loop. Recorded: the plant input u and the measured y (closed-loop
    data); r is in the truth."""
    rng = np.random.default_rng(seed)
    A = np.array([[0.0, 1.0], [0.0, -1.0 / tau_s]])
    B = np.array([[0.0], [k / tau_s]])
    Ad, Bd, *_ = signal.cont2discrete((A, B, np.eye(2), np.zeros((2, 1))), 1 / fs, "zoh")
    r = held_steps(n, rng, (int(fs), int(4 * fs)), amp=0.5)[:, 0]
    d = disturbance * rng.standard_normal(n)
    x = np.zeros(2)
    u, y_clean = np.empty(n), np.empty(n)
    noise_sd = 10 ** (-snr_db / 20) * 0.5
    integ = 0.0
    y_meas = np.empty(n)
    for t in range(n):
        y_clean[t] = x[0]
        y_meas[t] = x[0] + noise_sd * rng.standard_normal()
        e = r[t] - y_meas[t]
        if controller == "PI":
            integ += e / fs
            u[t] = kp * (e + integ / ti_s)
        else:
            u[t] = kp * e
        x = Ad @ x + Bd[:, 0] * (u[t] + d[t])
    truth = dict(kind="integrator", integrator=True, closed_loop=True, order=2, delays=[0.0],
                 poles=[0.0, -1 / tau_s], time_constants=[tau_s], plant=dict(k=k, tau_s=tau_s),
                 controller=dict(kind=controller, kp=kp, ti_s=ti_s), reference=r)
    return Generated(u[:, None], y_meas[:, None], fs, ["drive"], ["position"],
                     {"drive": "V", "position": "m"}, truth, y_clean[:, None])


def modal_ss(modes, phi_in: np.ndarray, phi_out: np.ndarray):
    """Continuous (A, B, C, D) of uncoupled modes q̈ + 2ζω q̇ + ω² q = ω²·φ_inᵀu,
    y = Σ φ_out q (displacement outputs): static gain Σ φ_out φ_inᵀ."""
    m = len(modes)
    nu, ny = phi_in.shape[1], phi_out.shape[0]
    A = np.zeros((2 * m, 2 * m))
    B = np.zeros((2 * m, nu))
    C = np.zeros((ny, 2 * m))
    for i, (f, z) in enumerate(modes):
        w = 2 * np.pi * f
        A[2 * i, 2 * i + 1] = 1.0
        A[2 * i + 1, 2 * i] = -w * w
        A[2 * i + 1, 2 * i + 1] = -2 * z * w
        B[2 * i + 1] = w * w * phi_in[i]
        C[:, 2 * i] = phi_out[:, i]
    return A, B, C, np.zeros((ny, nu))


def structure(modes, n_inputs: int = 2, n_outputs: int = 2, fs: float = 200.0,
              n: int = 8000, snr_db: float = 40.0, seed: int = 0, delays=None,
              force_rms: float = 5.0) -> Generated:
    """A structure with the given modes [(f Hz, ζ)], shakers (N) → displacements (mm), mode
    shapes random but fixed by ``seed`` (each entry of magnitude 0.3–1 mm/N·…), multisine
    forces from 0.3·f_min to 1.5·f_max (independent per shaker)."""
    rng = np.random.default_rng(seed)
    m = len(modes)

    def shapes(rows, cols):
        return rng.choice([-1, 1], (rows, cols)) * rng.uniform(0.3, 1.0, (rows, cols))

    phi_in, phi_out = shapes(m, n_inputs), shapes(n_outputs, m)
    fmin, fmax = min(f for f, _ in modes), max(f for f, _ in modes)
    u = multisine(n, fs, 0.3 * fmin, min(1.5 * fmax, 0.45 * fs), force_rms, rng, n_inputs)
    A, B, C, D = modal_ss(modes, phi_in, phi_out * 0.1)
    clean = simulate_ct(A, B, C, D, u, fs, delays)
    poles = np.linalg.eigvals(A)
    truth = dict(kind="structure", order=2 * m, modes=sorted(modes),
                 delays=list(np.zeros(n_inputs) if delays is None else delays),
                 poles=sorted(poles, key=lambda p: (abs(p), p.imag)),
                 dc_gain=(C @ np.linalg.solve(-A, B)).tolist(), integrator=False,
                 closed_loop=False, phi_in=phi_in, phi_out=phi_out * 0.1, abcd=(A, B, C, D))
    ins = [f"force{j + 1}" for j in range(n_inputs)]
    outs = [f"disp{i + 1}" for i in range(n_outputs)]
    return Generated(u, add_noise(clean, snr_db, rng), fs, ins, outs,
                     {**{c: "N" for c in ins}, **{c: "mm" for c in outs}}, truth, clean)


#: the 6 modes of :func:`structure_2in_6modes` (Hz, ζ)
SIX_MODES = [(3.1, 0.02), (7.4, 0.015), (12.9, 0.03), (19.5, 0.02), (27.3, 0.025),
             (41.0, 0.02)]
#: the 3 modes of :func:`structure_2in_3modes` (Hz, ζ)
THREE_MODES = [(0.41, 0.03), (1.13, 0.02), (2.37, 0.025)]


def structure_2in_6modes(seed: int = 0, n: int = 8000, **kw) -> Generated:
    """Two shakers, two displacement outputs, six modes 3–41 Hz, 200 Hz."""
    return structure(SIX_MODES, 2, 2, fs=200.0, n=n, seed=seed, **kw)


def structure_2in_3modes(seed: int = 0, n: int = 6000, n_outputs: int = 1, **kw
                         ) -> Generated:
    """Two shakers, one output (default), three modes 0.4–2.4 Hz, 10 Hz sampling."""
    return structure(THREE_MODES, 2, n_outputs, fs=10.0, n=n, seed=seed, **kw)
