"""Scales of one record, so that every bound, grid and threshold of an effect is relative.

Invariance by construction (issue 12, docs/diagnose.md "Invariance"): the findings and fits
must not change when a channel is given in other units or the same samples are given another
rate. So an effect states its constants relative to the record — in samples (the sampling
rate), as a share of the Nyquist frequency or of the estimation part's length, relative to the
model's own modes, or in units of a signal's spread — and converts them to the record's units
here, never in seconds, Hz or volts of one rig.

:class:`RecordScale` carries what those conversions need; :func:`pow2_floor` /
:func:`pow2_ceil` round segment lengths (samples).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rigd.effects._drive import drive_spread
from rigd.effects._signals import spread


@dataclass(frozen=True)
class RecordScale:
    """What an effect needs to turn its relative constants into the record's units.

    Attributes
    ----------
    fs : float
        Sampling rate, Hz.
    n : int
        Samples of the (estimation) data the bounds are for.
    u_spread, y_spread : ndarray
        Robust half-amplitude of each input / output
        (:func:`rigd.effects._signals.spread`), in its own unit.
    drive_spread : float
        Half-amplitude of the drives the valve effects act on (the recorded valve drives,
        else the inputs; :func:`rigd.effects._drive.drive_spread`).
    """

    fs: float
    n: int
    u_spread: np.ndarray
    y_spread: np.ndarray
    drive_spread: float

    @classmethod
    def of(cls, data: Any) -> RecordScale:
        """The scales of identification data (``fs``, ``inputs``, ``outputs``, drives)."""
        return cls(float(data.fs), int(np.asarray(data.outputs).shape[0]),
                   spread(data.inputs), spread(data.outputs), drive_spread(data))

    @property
    def nyquist_hz(self) -> float:
        return 0.5 * self.fs

    @property
    def lowest_hz(self) -> float:
        """Lowest frequency the (estimation) data can show: two periods in it, Hz."""
        return 2.0 * self.fs / max(self.n, 1)


def pow2_floor(x: float) -> int:
    """Largest power of two ≤ x (≥ 1)."""
    return 1 << max(0, int(np.floor(np.log2(max(float(x), 1.0)))))


def pow2_ceil(x: float) -> int:
    """Smallest power of two ≥ x (≥ 1)."""
    return 1 << max(0, int(np.ceil(np.log2(max(float(x), 1.0)))))
