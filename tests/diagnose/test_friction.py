"""``friction`` (Coulomb + viscous, requires a mechanical base), promoted from the dry-friction
probe into the catalogue.

The record comes from a positioning stage integrated here, independently of rigd's models
(explicit RK4 on a fine grid; a smooth Coulomb law with a 1 µm/s-scale transition): force
(N) -> position under a filtered random force. Controls without friction (a linear
oscillator, the cascaded tanks with overflow) are tests/diagnose/test_benchmark_records.py's
"nothing significant" cases.
"""

from __future__ import annotations

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


def _free_stage():
    return stage(seed=3, closed=False, m=10.0, c=30.0, fc=5.0)


@pytest.fixture(scope="module")
def free_stage_diagnosis(tmp_path_factory):
    """The default diagnosis of the free stage (``_free_stage``), made once per test run
    (tests/sharedruns.py: both tests below read it, on whichever worker they run)."""
    from sharedruns import shared_value

    return shared_value("diagnosis-friction-free-stage",
                        lambda: diagnose_record(_free_stage()), tmp_path_factory)


# a default diagnosis of 12,000 samples (the restoring-force hysteresis's RK4 refits among
# its screened effects): ≈ 5 min at load 10 on the 2-core machine, over 10 min at load 25
@pytest.mark.timeout(1800)
def test_dry_friction_named_with_its_size_and_error_falls(free_stage_diagnosis):
    """Coulomb friction of 5 N on a 10 kg stage under a random force: ``friction`` named, the
    held-out error falls ≥ 3×, the refitted Coulomb force (through the base's input gain) is
    the true 5 N within 30 %; the free mass is named an integrator from the base."""
    d = free_stage_diagnosis
    out = d.to_json()
    named = [f["effect"] for f in out["findings"] if f["significant"]]
    assert "friction" in named and "friction" in [s["added"] for s in out["steps"]], named
    final = out["steps"][-1]["fit_percent"]
    assert 100 - out["fit_percent"] >= 3 * (100 - final), out["steps"]
    step = next(s for s in d.parts[0].steps if s.added == "friction")
    st, th = step.structure, np.asarray(step.theta, float)
    fc = th[st.names.index("fr_c_1")]
    _, Bm, _, _, _ = st.continuous(th)
    assert fc / Bm[1, 0] == pytest.approx(5.0, rel=0.3), (fc, Bm)


# make test-long (CI): a second default diagnosis of 12,000 samples; the invariance of the
# catalogue is guarded in make test by tests/diagnose/test_metamorphic.py
@pytest.mark.long
@pytest.mark.timeout(3600)  # two default diagnoses of the stage (see above)
def test_friction_rescaled_same_diagnosis(free_stage_diagnosis):
    """The same stage with the position × 1000 (m → mm) and the rate × 1000: the same
    findings, steps and fits (±0.1 point; tests/diagnose/test_metamorphic.py's digest)."""
    import test_metamorphic as M

    rec = _free_stage()
    ref = M._digest(free_stage_diagnosis)
    assert "friction" in [added for added, _ in ref[1]], ref
    sy, sr = 1e3, 1e3
    M._same(ref, M._digest(diagnose_record(M._variant(rec, 1.0, sy, sr)), sr))
