"""Unit checks of the unexplained-structure localisation (rigd/diagnose/unexplained.py) on
synthetic residuals whose structure is known by construction: fast, no model fits."""

import numpy as np
import pytest

from rigd.diagnose import unexplained as U

PASSED = {"whiteness": {"y": {"passed": True, "outside": 0.0}},
          "cross_correlation": {"y~u": {"passed": True, "outside": 0.0}}}


def test_noise_estimate_of_a_smooth_signal_plus_white_noise():
    rng = np.random.default_rng(0)
    t = np.arange(20000) / 1000.0
    x = np.sin(2 * np.pi * 3.0 * t) + 0.02 * rng.standard_normal(t.size)
    assert 0.9 * 0.02 <= U.noise_rms(x) <= 1.15 * 0.02


def test_white_residual_at_the_noise_level_reports_nothing():
    rng = np.random.default_rng(1)
    n = 6000
    u = rng.standard_normal((n, 1))
    y = np.cumsum(rng.standard_normal((n, 1)), axis=0) * 0.01 + 0.0  # smooth output
    r = 0.05 * rng.standard_normal((n, 1))
    assert U.report(r, y + r, y, u, 100.0, PASSED, [], ["y"], ["u"]) == []


@pytest.mark.parametrize("fs", [1.0, 200.0, 5000.0])
def test_band_peak_with_the_digits_the_rate_supports(fs):
    """A line at 0.06275·fs: reported at that frequency with the resolution's digits at any
    rate (at fs = 1 Hz: 0.0627 Hz, never "0.1 Hz"), share of its energy 0..1."""
    rng = np.random.default_rng(2)
    n = 8000
    k = np.arange(n)
    r = (np.sin(2 * np.pi * 0.06275 * k + 0.3) + 0.1 * rng.standard_normal(n))[:, None]
    out = U.bands(r, fs, 0.01)
    assert out, out
    b = out[0]
    assert abs(b["frequency_hz"] - 0.06275 * fs) <= b["resolution_hz"], b
    assert b["band_hz"][0] <= b["frequency_hz"] <= b["band_hz"][1] < fs / 2
    assert 0.9 <= b["share"] <= 1.0
    assert f"{b['frequency_hz']:g}" != f"{0.1 * fs:g}"


def test_time_segment_of_a_burst_and_not_of_a_narrow_band_residual():
    rng = np.random.default_rng(3)
    n = 5000
    r = 0.1 * rng.standard_normal(n)
    r[2000:2400] += rng.standard_normal(400)  # a disturbance in samples 2000..2400
    seg = U.segments(r[:, None])
    assert seg is not None and seg["samples"][0] <= 2000 and seg["samples"][1] >= 2400
    assert 0.5 <= seg["share"] <= 1.0
    # a stationary narrow-band residual: its energy fluctuates, but by chance only
    k = np.arange(n)
    for s in range(4):
        ph = np.random.default_rng(10 + s).uniform(0, 2 * np.pi, 5)
        nb = sum(np.sin(2 * np.pi * (0.0625 + 0.0005 * i) * k + p) for i, p in enumerate(ph))
        assert U.segments(nb[:, None]) is None


def test_direction_of_input_motion():
    n = 8000
    t = np.arange(n) / 100.0
    u = np.sin(2 * np.pi * 0.5 * t)
    rng = np.random.default_rng(4)
    rising = np.gradient(u) > 0
    r = rng.standard_normal(n) * np.where(rising, 1.0, 0.3)
    d = U.direction(r[:, None], u[:, None], ["u"])
    assert d is not None and d["worse"] == "rises" and d["ratio"] > 5
    assert 0.8 <= d["share"] <= 1.0
    assert U.direction(rng.standard_normal((n, 1)), u[:, None], ["u"]) is None


def test_saturation_of_the_output_localised_at_its_top_in_record_units():
    """A clipped output (the measurement flattens at its top while the model goes on):
    the amplitude range is the top of the measured range, with the offset added back."""
    n = 6000
    t = np.arange(n) / 50.0
    rng = np.random.default_rng(5)
    yhat = np.sin(2 * np.pi * 0.2 * t) + 0.5 * np.sin(2 * np.pi * 0.07 * t)
    y = np.minimum(yhat, 0.8) + 0.01 * rng.standard_normal(n)
    u = yhat.copy()
    tests = {"whiteness": {"y": {"passed": False, "outside": 0.9}}, "cross_correlation": {}}
    out = U.report((y - yhat)[:, None], y[:, None], yhat[:, None], u[:, None], 50.0, tests,
                   [], ["y"], ["u"], offsets={"y": 5.0})
    assert out and out[0]["where"]["residual"] == "structured"
    sat = [e for e in out if e["where"].get("saturation") == "top"]
    assert sat, [e["text"] for e in out]
    lo, hi = sat[0]["where"]["amplitude_range"]
    assert 5.0 + 0.7 <= lo < hi <= 5.0 + 0.85
    assert all(0.0 <= e["share"] <= 1.0 for e in out)
    assert sat[0]["share"] >= 0.9
