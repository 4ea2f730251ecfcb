"""Matrix exponential compiled without the GIL, for the simulated plant's parameter blocks.

An operating-point change builds the plant's discretisation (ZOH/FOH, :mod:`.params`) in
the caller's thread while the 5 kHz loop thread runs. ``scipy.linalg.expm`` holds the GIL
while it works, and every GIL hand-over can cost the loop thread a period (docs/loop.md, the
``op_change_miss_fraction`` bench figure); this version runs with the GIL released.

Scaling and squaring with the degree-13 Padé approximant (Higham, "The scaling and squaring
method for the matrix exponential revisited", SIAM J. Matrix Anal. Appl. 26(4), 2005,
Algorithm 2.3): backward error at the level of unit roundoff for every ``||A||_1``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Padé 13 coefficients b_0..b_13 (Higham 2005, Table 2.3 ff.)
_B = np.array([64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
               1187353796428800.0, 129060195264000.0, 10559470521600.0, 670442572800.0,
               33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0])
#: largest ||A||_1 for which Padé 13 needs no scaling (Higham 2005, Table 2.3)
THETA_13 = 5.371920351148152


@njit(cache=True, nogil=True)
def expm(a):
    """e^A of a square float64 matrix (see module docstring); runs without the GIL."""
    n = a.shape[0]
    norm1 = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += abs(a[i, j])
        norm1 = max(norm1, s)
    sq = 0
    if norm1 > THETA_13:
        sq = max(0, int(math.ceil(math.log2(norm1 / THETA_13))))
    A = np.ascontiguousarray(a) / (2.0 ** sq)
    ident = np.eye(n)
    b = _B
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    W = A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 \
        + b[1] * ident
    U = A @ W
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 \
        + b[0] * ident
    R = np.ascontiguousarray(np.linalg.solve(V - U, V + U))
    for _ in range(sq):
        R = R @ R
    return R
