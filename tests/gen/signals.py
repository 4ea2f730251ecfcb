"""Excitations for the generated records (deterministic given the generator)."""

from __future__ import annotations

import numpy as np


def held_steps(n: int, rng: np.random.Generator, hold: tuple[int, int], amp: float = 1.0,
               channels: int = 1, levels: int | None = None) -> np.ndarray:
    """(n, channels) random levels in [−amp, amp] held for a random number of samples in
    ``hold`` (inclusive); ``levels``: that many equally spaced levels (else uniform)."""
    out = np.empty((n, channels))
    for c in range(channels):
        k = 0
        while k < n:
            d = int(rng.integers(hold[0], hold[1] + 1))
            if levels:
                v = amp * (2 * rng.integers(0, levels) / max(levels - 1, 1) - 1)
            else:
                v = amp * rng.uniform(-1, 1)
            out[k:k + d, c] = v
            k += d
    return out


def multisine(n: int, fs: float, f_lo: float, f_hi: float, rms: float,
              rng: np.random.Generator, channels: int = 1) -> np.ndarray:
    """(n, channels) random-phase multisines on the DFT grid of n samples, flat from
    ``f_lo`` to ``f_hi`` (Hz), scaled to ``rms``; independent phases per channel."""
    k = np.arange(n // 2 + 1)
    f = k * fs / n
    band = (f >= f_lo) & (f <= f_hi)
    out = np.empty((n, channels))
    for c in range(channels):
        spec = np.zeros(len(k), complex)
        spec[band] = np.exp(2j * np.pi * rng.uniform(size=band.sum()))
        x = np.fft.irfft(spec, n)
        out[:, c] = rms * x / np.std(x)
    return out
