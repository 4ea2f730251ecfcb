"""Excitation signals for the lumped valve references r_x, r_y (V, added to K∞'s output).

Every function returns a float64 array of shape (n, 2): column 0 is r_x, column 1 is r_y. A
quiet lead-in (zeros) of ``lead_in_s`` comes first so that sensor offsets can be estimated
from the record before the excitation starts. Signals are deterministic for a given seed.

* :func:`prbs` — pseudo-random binary sequence, ±amplitude, switching at "bit" boundaries
  every ``min_hold_s`` with probability ``switch_probability`` (the paper's identification
  signal; two levels only, so it cannot reveal amplitude-dependent effects).
* :func:`multilevel` — the same clocking, but a random level out of ``levels`` equally spaced
  values in [-A, A] (shows hysteresis and stiffening, which a PRBS hides).
* :func:`multisine` — periodic sum of sines on a frequency grid fs/N with random phases.
* :func:`chirp` — swept sine from ``f0_hz`` to ``f1_hz``.
"""

from __future__ import annotations

import numpy as np

AXES = ("x", "y")


def _n(seconds: float, fs: float) -> int:
    return int(round(seconds * fs))


def _rng(seed: int, axis: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), axis])


def _axis_amplitudes(amplitude: float | tuple[float, float] | list[float],
                     axes: tuple[str, ...] | list[str]) -> list[float]:
    if np.isscalar(amplitude):
        amps = [float(amplitude)] * 2
    else:
        amps = [float(a) for a in amplitude]  # type: ignore[union-attr]
    return [amps[i] if ax in axes else 0.0 for i, ax in enumerate(AXES)]


def _with_lead_in(sig: np.ndarray, lead_in_s: float, fs: float) -> np.ndarray:
    lead = np.zeros((_n(lead_in_s, fs), 2))
    return np.ascontiguousarray(np.vstack([lead, sig]))


def hold_pattern(n: int, hold: int, p: float, rng: np.random.Generator) -> np.ndarray:
    """Boolean per-sample "switch here" mask: switches only at multiples of ``hold`` samples,
    each with probability ``p``; never at sample 0."""
    n_bits = -(-n // hold)
    flips = rng.random(n_bits) < p
    flips[0] = False
    mask = np.zeros(n, dtype=bool)
    mask[np.arange(n_bits)[flips] * hold] = True
    return mask


def prbs(fs: float, duration_s: float, amplitude: float | list[float], *,
         switch_probability: float = 0.5, min_hold_s: float | None = None, seed: int = 0,
         axes=AXES, lead_in_s: float = 0.0) -> np.ndarray:
    """Pseudo-random binary sequence per axis, levels ±amplitude (V).

    Parameters
    ----------
    fs : float
        Loop rate, Hz.
    duration_s : float
        Length of the excitation after the lead-in, s.
    amplitude : float or [ax, ay]
        Level, V.
    switch_probability : float
        Probability of a level change at each bit boundary (0 < p <= 1).
    min_hold_s : float, optional
        Bit length (minimum time between switches), s; default one sample.
    seed : int
        Random seed; axis x and y use independent streams of it.
    axes : sequence of "x", "y"
        Axes to excite (others stay at 0).
    lead_in_s : float
        Quiet lead-in before the sequence, s.
    """
    n = _n(duration_s, fs)
    hold = max(1, _n(min_hold_s, fs)) if min_hold_s else 1
    amps = _axis_amplitudes(amplitude, axes)
    out = np.zeros((n, 2))
    for i in range(2):
        if amps[i] == 0.0:
            continue
        rng = _rng(seed, i)
        start = 1.0 if rng.random() < 0.5 else -1.0
        flips = np.cumsum(hold_pattern(n, hold, switch_probability, rng))
        out[:, i] = amps[i] * start * np.where(flips % 2 == 0, 1.0, -1.0)
    return _with_lead_in(out, lead_in_s, fs)


def multilevel(fs: float, duration_s: float, amplitude: float | list[float], *, levels: int = 5,
               switch_probability: float = 1.0, min_hold_s: float | None = None, seed: int = 0,
               axes=AXES, lead_in_s: float = 0.0) -> np.ndarray:
    """Random multi-level sequence: at each switch a new level (different from the current)
    out of ``levels`` values equally spaced in [-A, A]."""
    n = _n(duration_s, fs)
    hold = max(1, _n(min_hold_s, fs)) if min_hold_s else 1
    amps = _axis_amplitudes(amplitude, axes)
    grid = np.linspace(-1.0, 1.0, levels)
    out = np.zeros((n, 2))
    for i in range(2):
        if amps[i] == 0.0:
            continue
        rng = _rng(seed, i)
        mask = hold_pattern(n, hold, switch_probability, rng)
        n_seg = int(mask.sum()) + 1
        # each new level differs from the previous: step by 1..levels-1 (mod levels)
        steps = rng.integers(1, levels, size=n_seg)
        steps[0] = rng.integers(0, levels)
        idx = np.cumsum(steps) % levels
        out[:, i] = amps[i] * grid[idx[np.cumsum(mask)]]
    return _with_lead_in(out, lead_in_s, fs)


def multisine_lines(fs: float, period_s: float, f_min_hz: float, f_max_hz: float,
                    lines: str = "all") -> tuple[int, np.ndarray]:
    """Samples per period and excited harmonic numbers k (frequencies k·fs/N)."""
    n_per = max(2, _n(period_s, fs))
    f0 = fs / n_per
    k = np.arange(max(1, int(np.ceil(f_min_hz / f0))), int(np.floor(f_max_hz / f0)) + 1)
    k = k[k < n_per / 2]
    if lines == "odd":
        k = k[k % 2 == 1]
    return n_per, k


def multisine(fs: float, amplitude: float | list[float], *, period_s: float, periods: int,
              f_min_hz: float, f_max_hz: float, lines: str = "all", seed: int = 0, axes=AXES,
              lead_in_s: float = 0.0) -> np.ndarray:
    """Periodic random-phase multisine, scaled to peak ``amplitude`` (V) per axis."""
    n_per, k = multisine_lines(fs, period_s, f_min_hz, f_max_hz, lines)
    amps = _axis_amplitudes(amplitude, axes)
    t = np.arange(n_per)
    out = np.zeros((n_per, 2))
    for i in range(2):
        if amps[i] == 0.0 or k.size == 0:
            continue
        ph = _rng(seed, i).uniform(0, 2 * np.pi, size=k.size)
        x = np.zeros(n_per)
        for kk, p in zip(k, ph):
            x += np.cos(2 * np.pi * kk * t / n_per + p)
        out[:, i] = amps[i] * x / np.max(np.abs(x))
    return _with_lead_in(np.tile(out, (periods, 1)), lead_in_s, fs)


def chirp(fs: float, duration_s: float, amplitude: float | list[float], *, f0_hz: float,
          f1_hz: float, method: str = "logarithmic", axes=AXES,
          lead_in_s: float = 0.0) -> np.ndarray:
    """Swept sine from ``f0_hz`` to ``f1_hz`` over ``duration_s`` (scipy.signal.chirp)."""
    from scipy.signal import chirp as _chirp

    n = _n(duration_s, fs)
    t = np.arange(n) / fs
    amps = _axis_amplitudes(amplitude, axes)
    base = _chirp(t, f0=f0_hz, t1=max(t[-1], 1.0 / fs) if n else 1.0, f1=f1_hz, method=method)
    out = np.zeros((n, 2))
    for i in range(2):
        if amps[i] != 0.0:
            # y is a quarter period shifted (sine instead of cosine): uncorrelated axes
            out[:, i] = amps[i] * (base if i == 0 else
                                   _chirp(t, f0=f0_hz, t1=max(t[-1], 1.0 / fs),
                                          f1=f1_hz, method=method, phi=-90))
    return _with_lead_in(out, lead_in_s, fs)
