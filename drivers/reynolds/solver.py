"""Periodic block-tridiagonal linear solver (compiled, allocation-free) for the film Jacobian.

The film unknowns ordered z-fast (k = i·mz + j) give, with the 5-point stencil and periodic θ,
rows A_i x_{i−1} + B_i x_i + C_i x_{i+1} = d_i (indices mod n) with A_i, C_i diagonal and B_i
tridiagonal (stored dense). :func:`block_cyclic_solve` solves it for several right-hand sides
at once (the Newton residual and the low-rank update columns).
"""

from __future__ import annotations

import numba

# The block size as a type: passed as ``mtag``, a tuple of that length makes the size a
# compile-time constant (``len(mtag)``), so the compiler unrolls the m-loops; an empty tuple
# leaves it to the arrays' shape. The default grid (n_z = 8) has m = 4: the copy compiled for
# it runs the same operations in the same order, ≈ 2× faster.
M4 = (0, 0, 0, 0)


@numba.njit(cache=True, nogil=True)
def inv_small(a, out, m):
    """out = a⁻¹ (m × m, Gauss–Jordan with partial pivoting; a is overwritten)."""
    _inv(a, out, m, ())


@numba.njit(cache=True, nogil=True)
def _inv(a, out, m, mtag):
    """:func:`inv_small` with the size a compile-time constant when ``mtag`` is not empty
    (``len(mtag)``, see :data:`M4`)."""
    if len(mtag) > 0:
        m = len(mtag)
    for r in range(m):
        for s in range(m):
            out[r, s] = 1.0 if r == s else 0.0
    for col in range(m):
        piv = col
        big = abs(a[col, col])
        for r in range(col + 1, m):
            if abs(a[r, col]) > big:
                big = abs(a[r, col])
                piv = r
        if piv != col:
            for s in range(m):
                t = a[col, s]
                a[col, s] = a[piv, s]
                a[piv, s] = t
                t = out[col, s]
                out[col, s] = out[piv, s]
                out[piv, s] = t
        d = 1.0 / a[col, col]
        for s in range(m):
            a[col, s] *= d
            out[col, s] *= d
        for r in range(m):
            if r != col:
                f = a[r, col]
                if f != 0.0:
                    for s in range(m):
                        a[r, s] -= f * a[col, s]
                        out[r, s] -= f * out[col, s]


@numba.njit(cache=True, nogil=True)
def block_cyclic_solve(jA, jB, jC, d, nrhs, Dinv, E, T1, T2, Fb, G, g):
    """Solve the periodic block-tridiagonal system in place: ``d`` ← x (see :func:`_solve`);
    the default grid's 4 × 4 blocks by a copy compiled for that size."""
    if jB.shape[1] == 4:
        _solve(jA, jB, jC, d, nrhs, Dinv, E, T1, T2, Fb, G, g, M4)
    else:
        _solve(jA, jB, jC, d, nrhs, Dinv, E, T1, T2, Fb, G, g, ())


@numba.njit(cache=True, nogil=True)
def _solve(jA, jB, jC, d, nrhs, Dinv, E, T1, T2, Fb, G, g, mtag):
    """Solve the periodic block-tridiagonal system in place: ``d`` ← x.

    Row i: A_i x_{i−1} + B_i x_i + C_i x_{i+1} = d_i (indices mod n), A_i and C_i diagonal
    (``jA``, ``jC``: (n, m) diagonals), B_i dense (``jB``: (n, m, m), overwritten). ``d`` has
    shape (n, m, ≥nrhs); work arrays: Dinv, E (n, m, m), T1, T2, Fb, G (m, m), g (m, ≥nrhs).
    Periodic block Thomas: forward elimination carrying the spike column E_i (coupling to
    x_{n−1}), the bottom row reduced alongside, back substitution. ``mtag``: the block size
    as a compile-time constant, or ``()`` (:data:`M4`).
    """
    n = jB.shape[0]
    m = len(mtag) if len(mtag) > 0 else jB.shape[1]
    for i in range(n - 1):
        if i == 0:
            for a in range(m):
                for b in range(m):
                    E[0, a, b] = 0.0
                E[0, a, a] = jA[0, a]
        else:
            # L = A_i Dinv_{i−1}: row scaling
            for a in range(m):
                aa = jA[i, a]
                for b in range(m):
                    T1[a, b] = aa * Dinv[i - 1, a, b]
            for a in range(m):
                for b in range(m):
                    e = 0.0
                    for q in range(m):
                        e += T1[a, q] * E[i - 1, q, b]
                    jB[i, a, b] -= T1[a, b] * jC[i - 1, b]
                    E[i, a, b] = -e
                for r in range(nrhs):
                    s = 0.0
                    for q in range(m):
                        s += T1[a, q] * d[i - 1, q, r]
                    d[i, a, r] -= s
        if i == n - 2:
            for a in range(m):
                E[i, a, a] += jC[i, a]
        for a in range(m):
            for b in range(m):
                T2[a, b] = jB[i, a, b]
        _inv(T2, Dinv[i], m, mtag)
    # bottom row: Fb x_j + G x_{n−1} = g
    for a in range(m):
        for b in range(m):
            Fb[a, b] = 0.0
            G[a, b] = jB[n - 1, a, b]
        Fb[a, a] = jC[n - 1, a]
        for r in range(nrhs):
            g[a, r] = d[n - 1, a, r]
    for j in range(n - 1):
        if j == n - 2:
            for a in range(m):
                Fb[a, a] += jA[n - 1, a]
        for a in range(m):
            for b in range(m):
                s = 0.0
                for q in range(m):
                    s += Fb[a, q] * Dinv[j, q, b]
                T1[a, b] = s
        for a in range(m):
            for b in range(m):
                s = 0.0
                for q in range(m):
                    s += T1[a, q] * E[j, q, b]
                G[a, b] -= s
            for r in range(nrhs):
                s = 0.0
                for q in range(m):
                    s += T1[a, q] * d[j, q, r]
                g[a, r] -= s
        if j < n - 2:
            for a in range(m):
                for b in range(m):
                    Fb[a, b] = -T1[a, b] * jC[j, b]
    _inv(G, T2, m, mtag)
    for a in range(m):
        for r in range(nrhs):
            s = 0.0
            for q in range(m):
                s += T2[a, q] * g[q, r]
            d[n - 1, a, r] = s
    # back substitution x_j = Dinv_j (d_j − C_j x_{j+1} − E_j x_{n−1})
    for j in range(n - 2, -1, -1):
        for r in range(nrhs):
            for a in range(m):
                s = d[j, a, r]
                for q in range(m):
                    s -= E[j, a, q] * d[n - 1, q, r]
                if j < n - 2:
                    s -= jC[j, a] * d[j + 1, a, r]
                g[a, r] = s
            for a in range(m):
                s = 0.0
                for q in range(m):
                    s += Dinv[j, a, q] * g[q, r]
                d[j, a, r] = s


@numba.njit(cache=True, nogil=True)
def block_cyclic_resolve(jA, jC, d, Dinv, E, Ginv, g):
    """Solve again with the factors of the last solve (see :func:`_resolve`); 4 × 4 blocks by
    a copy compiled for that size."""
    if Dinv.shape[1] == 4:
        _resolve(jA, jC, d, Dinv, E, Ginv, g, M4)
    else:
        _resolve(jA, jC, d, Dinv, E, Ginv, g, ())


@numba.njit(cache=True, nogil=True)
def _resolve(jA, jC, d, Dinv, E, Ginv, g, mtag):
    """Solve again, for the first right-hand side column of ``d`` only (in place), with the
    factors a :func:`block_cyclic_solve` call left: ``Dinv`` and ``E`` (per block) and
    ``Ginv`` (the reduced bottom block's inverse, its ``T2``); ``jA`` and ``jC`` unchanged.

    O(n m²) instead of O(n m³): the bottom row's multipliers F_j D_j⁻¹ are applied by Horner's
    rule backwards (F_{j+1} = −F_j D_j⁻¹ diag(C_j)) instead of being formed. ``g``: work
    (m, ≥ 3). ``mtag`` as in :func:`_solve`.
    """
    n = Dinv.shape[0]
    m = len(mtag) if len(mtag) > 0 else Dinv.shape[1]
    # forward elimination: d_i −= diag(A_i) D_{i−1}⁻¹ d_{i−1}
    for i in range(1, n - 1):
        for a in range(m):
            s = 0.0
            for q in range(m):
                s += Dinv[i - 1, a, q] * d[i - 1, q, 0]
            d[i, a, 0] -= jA[i, a] * s
    # Σ_j F_j D_j⁻¹ d_j: u = D_{n−2}⁻¹ d_{n−2}; u ← D_j⁻¹ (d_j − C_j ∘ u), j = n−3 … 0
    for a in range(m):
        s = 0.0
        for q in range(m):
            s += Dinv[n - 2, a, q] * d[n - 2, q, 0]
        g[a, 1] = s                     # w_{n−2} (the A_{n−1} term)
        g[a, 0] = s                     # u
    for j in range(n - 3, -1, -1):
        for a in range(m):
            g[a, 2] = d[j, a, 0] - jC[j, a] * g[a, 0]
        for a in range(m):
            s = 0.0
            for q in range(m):
                s += Dinv[j, a, q] * g[q, 2]
            g[a, 0] = s
    for a in range(m):
        g[a, 2] = d[n - 1, a, 0] - jC[n - 1, a] * g[a, 0] - jA[n - 1, a] * g[a, 1]
    for a in range(m):
        s = 0.0
        for q in range(m):
            s += Ginv[a, q] * g[q, 2]
        d[n - 1, a, 0] = s
    # back substitution x_j = D_j⁻¹ (d_j − C_j x_{j+1} − E_j x_{n−1})
    for j in range(n - 2, -1, -1):
        for a in range(m):
            s = d[j, a, 0]
            for q in range(m):
                s -= E[j, a, q] * d[n - 1, q, 0]
            if j < n - 2:
                s -= jC[j, a] * d[j + 1, a, 0]
            g[a, 2] = s
        for a in range(m):
            s = 0.0
            for q in range(m):
                s += Dinv[j, a, q] * g[q, 2]
            d[j, a, 0] = s
