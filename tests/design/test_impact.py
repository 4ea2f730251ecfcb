"""Impact damping estimation on synthetic damped sinusoids with noise."""

import numpy as np
import pytest

from rigd.data.record import Record
from rigd.design.impact import analyze_record, fit_damped_sinusoid
from rigd.errors import InputError


def _response(f, zeta, fs=5000.0, dur=0.08, noise=0.0, amp=3.0, phi=0.7, seed=0):
    t = np.arange(int(dur * fs)) / fs
    wn = 2 * np.pi * f
    wd = wn * np.sqrt(1 - zeta ** 2)
    y = amp * np.exp(-zeta * wn * t) * np.cos(wd * t + phi) + 0.4
    y += noise * amp * np.random.default_rng(seed).standard_normal(len(t))
    return t, y


@pytest.mark.parametrize("f,zeta", [(111.0, 0.057), (143.0, 0.028), (125.0, 0.17),
                                    (160.0, 0.30)])
def test_fit_recovers_frequency_and_damping_with_noise(f, zeta):
    t, y = _response(f, zeta, noise=0.03)
    fit = fit_damped_sinusoid(t, y)
    assert fit.f_hz == pytest.approx(f, rel=0.02)
    assert fit.zeta == pytest.approx(zeta, rel=0.05)
    # the stated uncertainty is honest: the truth lies within 4 sigma
    assert abs(fit.zeta - zeta) < 4 * fit.zeta_std + 1e-4
    assert 0 < fit.zeta_std < 0.2 * zeta
    assert fit.fit_percent > 70


def test_noisier_data_gives_larger_uncertainty():
    t, y1 = _response(130.0, 0.1, noise=0.01)
    _, y2 = _response(130.0, 0.1, noise=0.1)
    assert fit_damped_sinusoid(t, y2).zeta_std > 3 * fit_damped_sinusoid(t, y1).zeta_std


def test_record_analysis_finds_impact_axis_and_fits_after_the_force():
    fs = 5000.0
    n = 1000
    t = np.arange(n) / fs
    fx = np.zeros(n)
    fx[50:55] = 40.0                                   # 1 ms impact at t = 10 ms
    ex = np.zeros(n)
    tt, y = _response(120.0, 0.08, dur=(n - 55) / fs, noise=0.01)
    ex[55:] = y - 0.4
    rec = Record({"t": t, "e_x": ex, "e_y": 0.01 * ex, "f_x": fx, "f_y": np.zeros(n)}, fs,
                 {"omega_rpm": 0.0, "p_inj_bar": 4.0})
    out = analyze_record(rec)
    assert list(out["axes"]) == ["x"]
    ax = out["axes"]["x"]
    assert ax["zeta"] == pytest.approx(0.08, rel=0.05)
    assert ax["f_hz"] == pytest.approx(120.0, rel=0.02)
    assert ax["t_impact_s"] == pytest.approx(0.010)


def test_record_without_impact_is_refused():
    n = 500
    rec = Record({"t": np.arange(n) / 5000.0, "e_x": np.zeros(n), "e_y": np.zeros(n),
                  "f_x": np.zeros(n), "f_y": np.zeros(n)}, 5000.0, source="run.h5")
    with pytest.raises(InputError, match="no impact"):
        analyze_record(rec)
