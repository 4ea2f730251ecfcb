"""Explanations with checked numbers: the helpers of rigd/effects/numbers.py (shares in
0–100 %, frequencies below Nyquist, distinct values printed distinctly, durations ≥ 0 in a
readable unit). The property tests over random generic systems (hypothesis) are in
test_explanations_property.py."""


import numpy as np
import pytest

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


def test_durations_in_a_readable_unit_never_negative():
    assert [N.duration(t) for t in (0.0, 4.3e-6, 0.00432, 0.5, 30.0, 1234.4)] == [
        "0 µs", "4.3 µs", "4.32 ms", "500 ms", "30 s", "1234 s"]
    for bad in (-0.06e-3, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            N.duration(bad)
    assert N.freqs([1229.4, 12.55]) == ["1229", "12.6"]  # no 1.23e+03
