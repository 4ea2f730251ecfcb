"""Records of systems simulated independently of rigd's models (scipy, in the test): other
structures, parameters and rates than the rotor rig's, for the domain-neutral catalogue
entries (static_nonlinearity, integrator).

Each returns a generic :class:`rigd.data.record.Record` with noise at ``snr_db``:

* :func:`hammerstein` — a valve with an equal-percentage characteristic (e^{αu} − 1)/α
  ahead of two real lags (τ = 1.5 s, 0.4 s), 20 Hz, multi-level steps;
* :func:`wiener` — the same lags followed by a sensor with a quadratic characteristic;
* :func:`integrator_loop` — an integrating plant K/(s (τ s + 1)) under proportional feedback
  from a random set-point, 10 Hz; the record holds the controller's output and the plant's.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from rigd.data.record import Record


def _levels(n: int, rng: np.random.Generator, hold=(4, 40), lo=-1.0, hi=1.0) -> np.ndarray:
    out = np.empty(n)
    k = 0
    while k < n:
        h = int(rng.integers(*hold))
        out[k:k + h] = rng.uniform(lo, hi)
        k += h
    return out


def _lsim_zoh(num, den, u: np.ndarray, fs: float) -> np.ndarray:
    """Output of num/den(s) to ``u`` held over each sample (exact ZOH discretisation)."""
    b, a, _ = signal.cont2discrete((num, den), 1.0 / fs, method="zoh")
    return signal.lfilter(np.ravel(b), a, u)


def _record(u, y, fs, rng, snr_db, names=("u", "y")) -> Record:
    y = y + 10 ** (-snr_db / 20) * np.std(y) * rng.standard_normal(y.shape)
    return Record({"t": np.arange(len(u)) / fs, names[0]: np.asarray(u, float),
                   names[1]: np.asarray(y, float)}, fs,
                  {"inputs": [names[0]], "outputs": [names[1]], "intersample": "zoh"},
                  source="<independent>")


LAGS = (np.array([1.0]), np.polymul([1.5, 1.0], [0.4, 1.0]))


def hammerstein(seed: int = 0, n: int = 1500, fs: float = 20.0, alpha: float = 1.6,
                snr_db: float = 40.0) -> Record:
    rng = np.random.default_rng(seed)
    u = _levels(n, rng)
    v = (np.exp(alpha * u) - 1.0) / alpha
    return _record(u, _lsim_zoh(*LAGS, v, fs), fs, rng, snr_db, ("valve", "flow"))


def wiener(seed: int = 0, n: int = 1500, fs: float = 20.0, c2: float = 0.4,
           snr_db: float = 40.0) -> Record:
    rng = np.random.default_rng(seed)
    u = _levels(n, rng)
    x = _lsim_zoh(*LAGS, u, fs)
    return _record(u, x + c2 * x ** 2, fs, rng, snr_db, ("drive", "sensor"))


def integrator_loop(seed: int = 0, n: int = 1500, fs: float = 10.0, k: float = 0.8,
                    tau: float = 0.5, kp: float = 1.5, snr_db: float = 40.0) -> Record:
    """y = K/(s(τs+1)) u, u = kp (r − y_meas) + dither; r random levels."""
    rng = np.random.default_rng(seed)
    r = _levels(n, rng, hold=(20, 120))
    dither = 0.2 * rng.standard_normal(n)
    A, B, C, _, _ = signal.cont2discrete(signal.tf2ss([k], [tau, 1.0, 0.0])[:3] + (0.0,),
                                         1.0 / fs, method="zoh")
    x = np.zeros(A.shape[0])
    y, u = np.zeros(n), np.zeros(n)
    # sensor noise at snr_db below the set-point's spread (the loop follows it)
    noise = 10 ** (-snr_db / 20) * np.std(r) * rng.standard_normal(n)
    for t in range(n):
        y[t] = (C @ x)[0] + noise[t]           # measured
        u[t] = kp * (r[t] - y[t]) + dither[t]
        x = A @ x + B[:, 0] * u[t]
    return Record({"t": np.arange(n) / fs, "u": u, "y": y}, fs,
                  {"inputs": ["u"], "outputs": ["y"], "intersample": "zoh"},
                  source="<independent>")
