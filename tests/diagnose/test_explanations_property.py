"""Explanations with checked numbers, property-based (hypothesis): on random generic systems —
stable one- or two-mode oscillators at a random sample rate, input and output scales, with one
random catalogue effect in the data or none — every number an explanation prints keeps its
bound: shares in 0–100 %, frequencies positive and below Nyquist (or said to be above it),
durations and delays ≥ 0 and time constants > 0, distinct values printed distinctly; and no
rotor word on a record that is not from a rotor.

Reproducible in CI: ``derandomize=True`` (examples derived from the test itself, no example
database), few examples, no deadline (a diagnosis takes seconds on a loaded machine), no
shrinking (a failure is reported with the example's parameters as drawn).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis import strategies as st
from scipy import signal

from rigd.data.record import Record
from rigd.diagnose.diagnosis import diagnose_record

#: words that only fit the rotor rig (film bearing, piezo valves, shaft encoder ...)
ROTOR_WORDS = ("film", "piezo", "valve", "gyroscop", "eccentricity", "r–u plane", "shaft",
               "encoder", "rpm", "bearing", "rotor")
NUM = r"(-?\d+(?:\.\d*)?(?:e[-+]?\d+)?)"
EFFECTS = ("none", "delay", "cubic_stiffness", "input_hysteresis", "creep", "extra_mode")

SYSTEMS = st.fixed_dictionaries({
    "seed": st.integers(0, 2 ** 16),
    "fs": st.floats(-1.0, 4.0).map(lambda e: float(f"{10 ** e:.6g}")),  # 0.1 Hz .. 10 kHz
    "modes": st.integers(1, 2),
    "u_scale": st.sampled_from([1e-3, 1.0, 1e3]),
    "y_scale": st.sampled_from([1e-6, 1e-3, 1.0, 1e3]),
    "effect": st.sampled_from(EFFECTS),
    "excitation": st.sampled_from(["noise", "steps"]),
})


def _play(u: np.ndarray, width: float) -> np.ndarray:
    """Play (backlash) operator of half-width ``width``: the output follows the input only
    once it has moved ``width`` past it (hysteresis at the input)."""
    out = np.empty_like(u)
    z = u[0]
    for i, x in enumerate(u):
        z = min(max(z, x - width), x + width)
        out[i] = z
    return out


def _modes(rng, fs, m):
    """m well-separated modes (f in 1–20 % of fs, ζ 2–20 %)."""
    f = np.sort(rng.uniform(0.01, 0.2, m)) * fs
    if m == 2 and f[1] < 1.6 * f[0]:
        f[1] = 1.6 * f[0]
    return 2 * np.pi * f, rng.uniform(0.02, 0.2, m)


def _simulate(u, fs, w, z, k3=0.0):
    """Sum of modes ẍ + 2ζω ẋ + ω² x (+ k3 x³ on the first) = ω² u, RK4 with 8 sub-steps,
    the input held over each sample."""
    n, h = len(u), 1.0 / (fs * 8)
    y = np.zeros(n)
    for k, (wk, zk) in enumerate(zip(w, z)):
        x = np.zeros(2)
        kk = k3 if k == 0 else 0.0

        def f(x, ui, wk=wk, zk=zk, kk=kk):
            return np.array([x[1], wk * wk * (ui - x[0]) - 2 * zk * wk * x[1] - kk * x[0] ** 3])

        for i in range(n):
            y[i] += x[0]
            for _ in range(8):
                a = f(x, u[i])
                b = f(x + 0.5 * h * a, u[i])
                c = f(x + 0.5 * h * b, u[i])
                d = f(x + h * c, u[i])
                x = x + h / 6 * (a + 2 * b + 2 * c + d)
    return y


def random_record(p: dict, n: int = 2000) -> Record:
    rng = np.random.default_rng(p["seed"])
    fs = p["fs"]
    if p["excitation"] == "noise":
        u = rng.standard_normal(n)
    else:  # multi-level steps held 5–60 samples (holds for creep and hysteresis to show)
        u = np.repeat(rng.choice([-1.0, -0.5, 0.0, 0.5, 1.0], n), rng.integers(5, 60, n))[:n]
    w, z = _modes(rng, fs, p["modes"])
    drive, k3 = u.copy(), 0.0
    if p["effect"] == "delay":
        d = int(rng.integers(1, 6))
        drive = np.concatenate([np.zeros(d), u[:-d]])
    elif p["effect"] == "input_hysteresis":
        drive = _play(u, 0.2)
    elif p["effect"] == "creep":  # a slow lag (20–100 samples) carrying 30 % of each step
        tau = rng.uniform(20, 100) / fs
        lag = signal.lfilter([1 - np.exp(-1 / (tau * fs))], [1, -np.exp(-1 / (tau * fs))], u)
        drive = 0.7 * u + 0.3 * lag
    elif p["effect"] == "cubic_stiffness":
        k3 = w[0] ** 2 * rng.uniform(0.5, 2.0) / np.std(u) ** 2
    y = _simulate(drive, fs, w, z, k3)
    if p["effect"] == "extra_mode":  # a third, lighter mode the data carry
        w3, z3 = _modes(rng, fs, 1)
        y = y + 0.3 * _simulate(drive, fs, 2.2 * w3, z3)
    y = y + 0.01 * np.std(y) * rng.standard_normal(n)
    return Record({"u": u * p["u_scale"], "y": y * p["y_scale"]}, fs,
                  {"inputs": ["u"], "outputs": ["y"]}, f"<random {p}>")


def check_text(t: str, fs: float) -> None:
    """Every bound of every number in one explanation, cannot-tell or unexplained text."""
    nyq = fs / 2
    low = t.lower()
    assert not [w for w in ROTOR_WORDS if w in low], t
    for v in re.findall(NUM + r" ?%", t):
        assert 0.0 <= float(v) <= 100.0, t
    for m in re.finditer(NUM + r" Hz", t):
        v = float(m.group(1))
        before = t[max(0, m.start() - 30):m.start()]
        if before.endswith("at ") and np.isclose(v, fs, rtol=1e-3):
            continue  # the sample rate itself ("3 samples at 500 Hz")
        if before.endswith("Nyquist frequency ("):
            assert np.isclose(v, nyq, rtol=1e-2), t
            continue
        assert 0.0 < v < nyq * 1.0001, t
    for m in re.finditer(NUM + r" ?(µs|ms|s)\b", t):
        v = float(m.group(1))
        assert v >= 0.0, t
        if re.search(r"(about|~|τ ?=?)\s*$", t[max(0, m.start() - 8):m.start()]):
            assert v > 0.0, t  # a time constant or delay stated as found
    for m in re.finditer(NUM + r" samples", t):
        assert float(m.group(1)) >= 0.0 or "not a delay" in t, t
    for lst in re.findall(r"\(model: ([^)]*?) Hz\)", t):
        vals = [s.strip() for s in lst.split(",")]
        assert len(set(vals)) == len(vals), t  # distinct resonances print distinctly
        assert all(float(v) > 0 for v in vals), t


@settings(max_examples=6, deadline=None, derandomize=True, database=None,
          phases=(Phase.explicit, Phase.generate),  # no shrinking: each example costs seconds
          suppress_health_check=[HealthCheck.too_slow])
@given(SYSTEMS)
# every catalogue effect at least once, whatever the draws (slow rates and small scales too)
@example({"seed": 3, "fs": 0.5, "modes": 1, "u_scale": 1e3, "y_scale": 1e-6,
          "effect": "creep", "excitation": "steps"})
@example({"seed": 4, "fs": 50.0, "modes": 2, "u_scale": 1.0, "y_scale": 1e-3,
          "effect": "input_hysteresis", "excitation": "steps"})
@example({"seed": 5, "fs": 2000.0, "modes": 1, "u_scale": 1e-3, "y_scale": 1e3,
          "effect": "extra_mode", "excitation": "noise"})
def test_explanation_numbers_keep_their_bounds(p):
    rec = random_record(p)
    out = diagnose_record(rec, refit=False).to_json()
    texts = ([f["explanation"] for f in out["findings"]]
             + [u["text"] for u in out["unexplained"]]
             + [c["why"] + " -> " + c["experiment"] for c in out["cannot_reveal"]])
    assert texts, out
    for t in texts:
        check_text(t, rec.fs)
    for u in out["unexplained"]:
        f = (u.get("where") or {}).get("frequency_hz")
        assert f is None or 0.0 <= f < rec.fs / 2, u
    for f in out["findings"]:
        assert 0.0 <= f["score"] <= 1.0 and 0.0 <= f["signature_score"] <= 1.0, f


@pytest.mark.parametrize("text, ok", [
    ("explains 12 % of the residual", True),
    ("creep 413784.1 % of the step", False),
    ("corner ≈ 11 Hz", False),                      # above the 0.5 Hz Nyquist of fs = 1 Hz
    ("corner above the Nyquist frequency (0.5 Hz)", True),
    ("a delay of -0.06 ms", False),
    ("a low-pass of about 0 ms", False),
    ("(model: 0.1, 0.1 Hz)", False),
    ("3 samples at 1 Hz", True),
    ("film stiffening at large eccentricity", False),
])
def test_the_checker_catches_the_numbers_seen(text, ok):
    """The property's checker refuses each kind of number issue 12 saw (fs = 1 Hz)."""
    if ok:
        check_text(text, 1.0)
    else:
        with pytest.raises(AssertionError):
            check_text(text, 1.0)
