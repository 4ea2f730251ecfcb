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


def test_the_copy_compiled_for_4x4_blocks_runs_the_same_operations():
    """The default grid's blocks (m = 4) go through a copy of the solver compiled with the
    block size as a constant (``M4``): it must give bit-for-bit what the copy that reads the
    size from the arrays gives (the same operations in the same order)."""
    from rigd_drivers.reynolds.solver import _resolve, _solve
    n, m, nr = 32, 4, 7
    rng = np.random.default_rng(7)
    jA, jC = rng.normal(size=(n, m)), rng.normal(size=(n, m))
    jB = rng.normal(size=(n, m, m)) + 6.0 * np.eye(m)
    d = rng.normal(size=(n, m, nr))
    b = rng.normal(size=(n, m))
    out = []
    for tag in (None, ()):                          # the dispatching entry, the generic copy
        work = [np.zeros((n, m, m)), np.zeros((n, m, m))] + [np.zeros((m, m)) for _ in range(4)]
        Dinv, E, T1, T2, Fb, G = work
        g = np.zeros((m, nr))
        x = d.copy()
        if tag is None:
            block_cyclic_solve(jA, jB.copy(), jC, x, nr, Dinv, E, T1, T2, Fb, G, g)
        else:
            _solve(jA, jB.copy(), jC, x, nr, Dinv, E, T1, T2, Fb, G, g, tag)
        x2 = x.copy()
        x2[:, :, 0] = b
        if tag is None:
            block_cyclic_resolve(jA, jC, x2, Dinv, E, T2, g)
        else:
            _resolve(jA, jC, x2, Dinv, E, T2, g, tag)
        out.append((x, x2))
    assert np.array_equal(out[0][0], out[1][0])
    assert np.array_equal(out[0][1], out[1][1])
    assert not np.array_equal(out[0][0], d)                 # it did solve
