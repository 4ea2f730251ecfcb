"""Probes for physics outside the catalogue (rigd.diagnose.probes): dry friction.

The records come from a positioning stage integrated here, independently of rigd's models
(explicit RK4 on a fine grid; a smooth Coulomb law with a 1 µm/s-scale transition): force
(N) -> position, open loop (a filtered random force) and closed loop (a PD position loop
driving the force, as the EMPS benchmark of Janot et al. is measured), several masses,
friction levels, units and rates. (On other stages the generic OE base model of a free mass
drifts or stops in a poor minimum — 11 % even without friction in a position loop, −84 % on
a random-walk validation part — and the probe has nothing sound to refit: a known limit of
output-error models of integrating plants, docs/diagnose.md.) Dry friction is not in the catalogue
(``../shared/DESIGN.md``): it must never be named as a finding, but described under
``unexplained`` with its size. Controls: the same stage without friction, the cascaded tanks
with overflow, and a Wiener–Hammerstein record — no friction reported.
"""

from __future__ import annotations

import benchmarks as B  # tests/diagnose/benchmarks.py
import numba
import numpy as np
import pytest
from scipy import signal

from rigd.data.record import Record
from rigd.diagnose.diagnosis import diagnose_record


@numba.njit(cache=True)
def _stage(f_in, ref, h, sub, m, c, fc, v_eps, kp, kd):
    n = f_in.shape[0] if ref.shape[0] == 0 else ref.shape[0]
    q = np.empty(n)
    force = np.empty(n)
    x, v = 0.0, 0.0
    for k in range(n):
        q[k] = x
        if ref.shape[0] == 0:
            f = f_in[k]
        else:                        # PD position loop, updated once per sample
            f = kp * (ref[k] - x) - kd * v
        force[k] = f
        for _ in range(sub):
            a1 = (f - c * v - fc * np.tanh(v / v_eps)) / m
            v2 = v + 0.5 * h * a1
            a2 = (f - c * v2 - fc * np.tanh(v2 / v_eps)) / m
            v3 = v + 0.5 * h * a2
            a3 = (f - c * v3 - fc * np.tanh(v3 / v_eps)) / m
            v4 = v + h * a3
            a4 = (f - c * v4 - fc * np.tanh(v4 / v_eps)) / m
            x += h / 6 * (v + 2 * v2 + 2 * v3 + v4)
            v += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    return force, q


def stage(seed=0, fs=1000.0, n=12000, m=95.0, c=200.0, fc=20.0, closed=True, unit=1.0,
          noise_m=2e-6):
    """(Record) force (N) -> position (m × ``unit``) of a friction stage."""
    rng = np.random.default_rng(seed)
    sub = 20
    h = 1.0 / (fs * sub)
    t = np.arange(n) / fs
    if closed:                       # slow sweeps back and forth, as a positioning test
        ref = 0.05 * np.sin(2 * np.pi * 0.4 * t) + 0.02 * np.sin(2 * np.pi * 1.3 * t + 1.0)
        ref += signal.lfilter(*signal.butter(2, 3.0, fs=fs), 0.01 * rng.standard_normal(n))
        f_in = np.zeros(0)
        kp, kd = 2.5e4 * m / 95.0, 1.5e3 * m / 95.0
    else:                            # a filtered random force
        ref = np.zeros(0)
        f_in = signal.lfilter(*signal.butter(2, 5.0, fs=fs), rng.standard_normal(n))
        f_in *= 4.0 * fc / np.std(f_in)
        kp = kd = 0.0
    force, q = _stage(f_in, ref, h, sub, m, c, fc, 1e-4, kp, kd)
    q = (q + noise_m * rng.standard_normal(n)) * unit
    force = force + 0.01 * fc * rng.standard_normal(n)
    meta = {"inputs": ["tau_N"], "outputs": ["q"], "units": {"tau_N": "N", "q": "m"}}
    return Record({"tau_N": force, "q": q}, fs, meta, f"<stage seed {seed}>")


def _friction(out):
    return [u for u in out["unexplained"] if "direction_of_motion" in u["where"]]


def emps_like(seed: int = 11, n: int = 20000) -> Record:
    """A stage in a PD position loop following a slow sine (EMPS-like), 1 kHz, Euler on the
    sample grid with a smooth Coulomb law (1 mm/s transition), m = 95 kg, c = 200 N s/m,
    F_c = 20 N; force and position measured with noise."""
    rng = np.random.default_rng(seed)
    fs, dt = 1000.0, 1e-3
    t = np.arange(n) * dt
    ref = signal.filtfilt(*signal.butter(2, 2, fs=fs), 0.1 * np.sin(2 * np.pi * 0.3 * t))
    m, c, fc = 95.0, 200.0, 20.0
    x = v = 0.0
    pos, force = np.zeros(n), np.zeros(n)
    for k in range(n):
        f = 2.5e4 * (ref[k] - x) - 1500.0 * v
        force[k] = f
        v += (f - c * v - fc * np.tanh(v / 1e-3)) / m * dt
        x += v * dt
        pos[k] = x
    meta = {"inputs": ["tau_N"], "outputs": ["q"], "units": {"tau_N": "N", "q": "m"}}
    return Record({"tau_N": force + 0.05 * rng.standard_normal(n),
                   "q": pos + 2e-6 * rng.standard_normal(n)}, fs, meta, "<emps-like>")


@pytest.mark.parametrize("make,true", [
    (lambda: stage(seed=3, closed=False, m=10.0, c=30.0, fc=5.0), 5.0),   # random force
    (lambda: emps_like(), 20.0),                                         # position loop
])
def test_dry_friction_described_with_its_size_never_named(make, true):
    out = diagnose_record(make()).to_json()
    sig = [f["effect"] for f in out["findings"] if f["significant"]]
    assert sig == [], sig                     # not a catalogue effect: nothing is named
    fr = _friction(out)
    assert len(fr) == 1, [u["text"] for u in out["unexplained"]]
    f = fr[0]
    assert f["friction"]["opposes_motion"] and "dry (Coulomb) friction" in f["text"]
    assert 0.10 <= f["share"] <= 1.0
    assert f["friction"]["size_input_units"] == pytest.approx(true, rel=0.3), f["text"]
    assert out["unexplained"][0]["where"]["residual"] == "structured"


def test_the_same_stage_without_friction_reports_none():
    rec = stage(seed=3, closed=False, m=10.0, c=30.0, fc=0.0)
    out = diagnose_record(rec).to_json()
    assert _friction(out) == [], [u["text"] for u in out["unexplained"]]


def test_friction_probe_is_unit_and_rate_free():
    kw = dict(seed=3, closed=False, m=10.0, c=30.0, fc=5.0)
    rec = stage(**kw)
    a = diagnose_record(rec).to_json()
    b_rec = Record({"tau_N": rec.col("tau_N") * 1e-3, "q": rec.col("q") * 1e6}, rec.fs * 1e3,
                   dict(rec.meta), "<rescaled>")
    b = diagnose_record(b_rec).to_json()
    fa, fb = _friction(a), _friction(b)
    assert len(fa) == len(fb) == 1
    assert fb[0]["share"] == pytest.approx(fa[0]["share"], abs=1e-3)
    # size in the input's units: the input was given in kN
    assert fb[0]["friction"]["size_input_units"] == pytest.approx(
        fa[0]["friction"]["size_input_units"] * 1e-3, rel=1e-3)


@pytest.mark.parametrize("make", [lambda: B.tank_overflow(seed=0),
                                  lambda: B.bouc_wen_linear(seed=0)])
def test_no_friction_reported_on_records_without_it(make):
    out = diagnose_record(make()).to_json()
    assert _friction(out) == [], [u["text"] for u in out["unexplained"]]
