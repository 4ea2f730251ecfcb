"""Excitation signals: levels, switching statistics, hold times, spectra, lead-in."""

import numpy as np
import pytest

from rigd.experiments import signals

FS = 5000.0


def _runs(x):
    """Lengths of constant runs."""
    edges = np.flatnonzero(np.diff(x) != 0) + 1
    return np.diff(np.concatenate([[0], edges, [len(x)]]))


def test_prbs_levels_switching_and_lead_in():
    sig = signals.prbs(FS, 4.0, [1.5, 0.8], switch_probability=0.3, min_hold_s=0.002,
                       seed=7, lead_in_s=0.1)
    lead = int(0.1 * FS)
    assert sig.shape == (lead + int(4.0 * FS), 2)
    assert not sig[:lead].any()
    x, y = sig[lead:, 0], sig[lead:, 1]
    assert set(np.unique(x)) == {-1.5, 1.5} and set(np.unique(y)) == {-0.8, 0.8}
    hold = int(0.002 * FS)
    for s in (x, y):
        runs = _runs(s)
        assert runs[:-1].min() >= hold and np.all(runs[:-1] % hold == 0)
        n_bits = len(s) // hold
        switches = np.count_nonzero(np.diff(s))
        # binomial(n_bits-1, 0.3): mean 0.3 n, sd ~ sqrt(0.21 n)
        assert abs(switches - 0.3 * (n_bits - 1)) < 4 * np.sqrt(0.21 * n_bits)
    assert abs(np.corrcoef(x, y)[0, 1]) < 0.1          # independent axes
    again = signals.prbs(FS, 4.0, [1.5, 0.8], switch_probability=0.3, min_hold_s=0.002,
                         seed=7, lead_in_s=0.1)
    assert np.array_equal(sig, again)
    other = signals.prbs(FS, 4.0, [1.5, 0.8], switch_probability=0.3, min_hold_s=0.002,
                         seed=8, lead_in_s=0.1)
    assert not np.array_equal(sig, other)


def test_prbs_single_axis():
    sig = signals.prbs(FS, 1.0, 1.0, axes=("y",), seed=1)
    assert not sig[:, 0].any() and set(np.unique(sig[:, 1])) == {-1.0, 1.0}


def test_multilevel_uses_all_levels_and_always_changes():
    sig = signals.multilevel(FS, 2.0, 2.0, levels=5, min_hold_s=0.004, seed=3)
    x = sig[:, 0]
    assert np.allclose(np.unique(x), [-2, -1, 0, 1, 2])
    runs = _runs(x)
    assert np.all(runs[:-1] == int(0.004 * FS))  # p = 1: a new level at every bit


def test_multisine_band_and_periodicity():
    sig = signals.multisine(FS, 1.0, period_s=0.2, periods=3, f_min_hz=10, f_max_hz=200,
                            lines="odd", seed=2)
    n_per = int(0.2 * FS)
    x = sig[:, 0]
    assert np.max(np.abs(x)) == pytest.approx(1.0)
    assert np.allclose(x[:n_per], x[n_per:2 * n_per])
    spec = np.abs(np.fft.rfft(x[:n_per]))
    k = np.flatnonzero(spec > 1e-6 * spec.max())
    f = k * FS / n_per
    assert f.min() >= 10 and f.max() <= 200 and np.all(k % 2 == 1)


def test_chirp_amplitude_and_sweep():
    sig = signals.chirp(FS, 2.0, 0.5, f0_hz=5, f1_hz=500, method="linear")
    x = sig[:, 0]
    assert np.max(np.abs(x)) <= 0.5 + 1e-12
    # zero-crossing rate grows: more crossings in the last quarter than the first
    q = len(x) // 4
    def zc(s):
        return np.count_nonzero(np.diff(np.sign(s)))

    assert zc(x[-q:]) > 5 * zc(x[:q])
