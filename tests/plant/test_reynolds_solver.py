"""The film Jacobian's periodic block-tridiagonal solver against a dense solve: the full solve
(several right-hand sides) and the chord re-solve that reuses its factors."""

import numpy as np
import pytest

from rigd_drivers.reynolds.solver import block_cyclic_resolve, block_cyclic_solve


def _dense(jA, jB, jC):
    n, m = jA.shape
    M = np.zeros((n * m, n * m))
    for i in range(n):
        rows = slice(i * m, (i + 1) * m)
        M[rows, rows] += jB[i]
        for j, diag in (((i - 1) % n, jA[i]), ((i + 1) % n, jC[i])):
            M[rows, j * m:(j + 1) * m] += np.diag(diag)
    return M


@pytest.mark.parametrize("n, m", [(2, 3), (3, 2), (5, 4), (32, 8)])
def test_solve_and_chord_resolve_match_a_dense_solve(n, m):
    rng = np.random.default_rng(n * 10 + m)
    jA, jC = rng.normal(size=(n, m)), rng.normal(size=(n, m))
    jB = rng.normal(size=(n, m, m)) + 6.0 * np.eye(m)
    M = _dense(jA, jB, jC)
    nr = 3
    d = rng.normal(size=(n, m, nr))
    rhs = d.reshape(n * m, nr).copy()
    Dinv, E = np.zeros((n, m, m)), np.zeros((n, m, m))
    T1, T2, Fb, G = (np.zeros((m, m)) for _ in range(4))
    g = np.zeros((m, nr))
    block_cyclic_solve(jA, jB.copy(), jC, d, nr, Dinv, E, T1, T2, Fb, G, g)
    assert np.allclose(d.reshape(n * m, nr), np.linalg.solve(M, rhs), rtol=1e-12, atol=1e-12)
    # a new first column, solved with the factors the full solve left (T2 = reduced G⁻¹)
    b = rng.normal(size=(n, m))
    d2 = d.copy()
    d2[:, :, 0] = b
    block_cyclic_resolve(jA, jC, d2, Dinv, E, T2, g)
    assert np.allclose(d2[:, :, 0].ravel(), np.linalg.solve(M, b.ravel()), rtol=1e-12,
                       atol=1e-12)
    assert np.array_equal(d2[:, :, 1:], d[:, :, 1:])        # the other columns kept
