"""Explanations with checked numbers: shares in 0–100 %, frequencies below Nyquist, distinct
values printed distinctly, rotor wording only on rotor records. Property tests over random
generic systems (seeded numpy draws; the hypothesis package is not in the test extra)."""

import re

import numpy as np
import pytest
from scipy import signal

from rigd.data.record import Record
from rigd.diagnose.diagnosis import diagnose_record
from rigd.effects import numbers as N

ROTOR_WORDS = ("film", "piezo", "valve", "gyroscop", "eccentricity", "r–u plane")


def test_frequencies_keep_distinct_values_distinct():
    rng = np.random.default_rng(0)
    for _ in range(500):
        v = 10.0 ** rng.uniform(-3, 4, size=int(rng.integers(2, 6)))
        if rng.random() < 0.5:  # near neighbours
            v[1] = v[0] * (1 + 10.0 ** rng.uniform(-6, -2))
        txt = N.freqs(v)
        for i in range(len(v)):
            for j in range(i + 1, len(v)):
                if not np.isclose(v[i], v[j], rtol=1e-9):
                    assert txt[i] != txt[j], (v, txt)
    assert N.freqs([0.06, 0.12]) == ["0.06", "0.12"]


def test_share_and_nyquist_bounds():
    for x in (-3.0, 0.0, 0.37, 1.0, 4137.841, float("nan")):
        pct = float(N.share(x).split()[0])
        assert 0.0 <= pct <= 100.0
    assert "Nyquist" in N.freq(11.0, 1.0) and "Nyquist" in N.freq(float("inf"), 1.0)
    assert N.freq(0.2, 1.0) == "0.2 Hz"


def _random_system(seed):
    """A random stable 1- or 2-mode system at a random rate and scale, multisine input."""
    rng = np.random.default_rng(seed)
    fs = float(10.0 ** rng.uniform(-1, 4))
    n = 3000
    modes = int(rng.integers(1, 3))
    num, den = np.array([0.0]), np.array([1.0])
    for _ in range(modes):
        w = 2 * np.pi * fs * rng.uniform(0.01, 0.2)
        z = rng.uniform(0.01, 0.2)
        num = np.polyadd(np.polymul(num, [1, 2 * z * w, w * w]), np.polymul(den, [w * w]))
        den = np.polymul(den, [1, 2 * z * w, w * w])
    u = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3)
    _, y = signal.dlsim(signal.cont2discrete((num, den), 1 / fs, "zoh"), u)
    y = y[:, 0] * 10.0 ** rng.uniform(-6, 3)
    y = y + 0.02 * np.std(y) * rng.standard_normal(n)
    return Record({"u": u, "y": y}, fs, {"inputs": ["u"], "outputs": ["y"]}, f"<rand {seed}>")


@pytest.mark.parametrize("seed", range(6))
def test_explanation_numbers_on_random_generic_systems(seed):
    rec = _random_system(seed)
    out = diagnose_record(rec, refit=False).to_json()
    nyq = rec.fs / 2
    texts = ([f["explanation"] for f in out["findings"]]
             + [u["text"] for u in out["unexplained"]]
             + [c["why"] + " " + c["experiment"] for c in out["cannot_reveal"]
                if c["effect"] not in ("runout", "cross_coupling", "hysteresis", "creep")])
    for t in texts:
        assert not any(w in t for w in ROTOR_WORDS), t
        for pct in re.findall(r"(-?[\d.]+(?:e[-+]?\d+)?) %", t):
            assert 0.0 <= float(pct) <= 100.0, t
        for hz in re.findall(r"(-?[\d.]+(?:e[-+]?\d+)?) Hz", t):
            assert 0.0 <= float(hz) <= nyq * 1.0001 or f"{hz} Hz)" in t, t
        for ms in re.findall(r"(-?[\d.]+(?:e[-+]?\d+)?) ms", t):
            assert float(ms) >= 0.0, t
    for u in out["unexplained"]:
        f = u["where"].get("frequency_hz")
        assert f is None or 0.0 <= f < nyq, u
