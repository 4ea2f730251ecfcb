"""Least squares on a tall matrix built chunk by chunk: the R factor of its QR decomposition
is accumulated (R ← qr([R; rows])) so memory stays (width², chunk·width), never n × n or a
whole n × width regressor matrix."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg

#: rows per chunk of the accumulated QR
CHUNK = 8192


def stacked_r(rows: Callable[[int, int], np.ndarray], n: int, width: int,
              chunk: int = CHUNK) -> np.ndarray:
    """Upper-triangular R (width, width) with RᵀR = MᵀM, M the (n, width) matrix whose rows
    ``t0:t1`` ``rows(t0, t1)`` returns."""
    R = np.zeros((0, width))
    for t0 in range(0, n, chunk):
        block = np.vstack([R, rows(t0, min(n, t0 + chunk))])
        R = scipy.linalg.qr(block, mode="r", overwrite_a=True, check_finite=False)[0]
        R = R[:width]
    if R.shape[0] < width:
        R = np.vstack([R, np.zeros((width - R.shape[0], width))])
    return R


def solve_r(R: np.ndarray, d: int) -> np.ndarray:
    """Least-squares coefficients (d, width − d) of the last columns of M on its first ``d``
    columns, from M's R factor (minimum-norm where the regressors are rank deficient)."""
    return np.linalg.lstsq(R[:d, :d], R[:d, d:], rcond=None)[0]
