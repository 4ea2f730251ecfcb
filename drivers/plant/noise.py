"""Seeded, counter-based Gaussian noise for the plant kernel (no hidden global RNG state).

``uniform(seed, ctr)`` hashes (seed, counter) with SplitMix64, so the noise of a step depends
only on the seed and the draw counter kept in the plant state: same seed and same inputs give
bit-identical records, whatever else runs in the process.
"""

from __future__ import annotations

import math

import numba
import numpy as np

TWO_PI = 2.0 * math.pi

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xBF58476D1CE4E5B9)
_M3 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)


@numba.njit(cache=True, nogil=True)
def uniform(seed, ctr):
    """Counter-based uniform in (0, 1): SplitMix64 of seed + ctr·golden."""
    z = np.uint64(seed) + np.uint64(ctr) * _M1
    z = (z ^ (z >> _S30)) * _M2
    z = (z ^ (z >> _S27)) * _M3
    z = z ^ (z >> _S31)
    return (float(z >> _S11) + 0.5) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, nogil=True)
def normal_pair(seed, ctr):
    """Two independent standard normals (Box–Muller) from draws ctr and ctr + 1."""
    u1 = uniform(seed, ctr)
    u2 = uniform(seed, ctr + 1.0)
    r = math.sqrt(-2.0 * math.log(u1))
    return r * math.cos(TWO_PI * u2), r * math.sin(TWO_PI * u2)


@numba.njit(cache=True, nogil=True)
def sensor_noise(seed, ctr, ne, ny):
    """The six standard normals of one sensor sample (draws ctr … ctr + 5).

    ``(n0, n1)`` for the two displacement sensors (zeros when ``ne`` = 0), ``(n2 … n5)`` for
    the four valve-position sensors (zeros when ``ny`` = 0); the caller scales them by ``ne``
    and ``ny`` and advances its draw counter by 6 either way.
    """
    n0 = 0.0
    n1 = 0.0
    n2 = 0.0
    n3 = 0.0
    n4 = 0.0
    n5 = 0.0
    if ne != 0.0:
        n0, n1 = normal_pair(seed, ctr)
    if ny != 0.0:
        n2, n3 = normal_pair(seed, ctr + 2.0)
        n4, n5 = normal_pair(seed, ctr + 4.0)
    return n0, n1, n2, n3, n4, n5
