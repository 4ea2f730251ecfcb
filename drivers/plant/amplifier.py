"""The piezo amplifier of the simulated plants: what a commanded drive voltage becomes."""

from __future__ import annotations

import numba


@numba.njit(cache=True, nogil=True)
def amplifier_output(v):
    """The amplifier output (V) for the commanded drive ``v`` (V): clamped to [0, 10] V; a NaN
    drive holds 0 V."""
    if v < 0.0:
        v = 0.0
    elif v > 10.0:
        v = 10.0
    if v != v:                             # NaN drive: amplifier holds 0 V
        v = 0.0
    return v
