"""Sanity checks of a fitted model: unstable modes and parameters at their bounds.

A fit can end with a mode of negative damping (its free response grows) or with a parameter
pressed against a bound (the data wanted more than the structure allows). Neither may be
used silently: :func:`model_warnings` returns one sentence per problem; ``rigd identify``
prints them and stores them in the model file (``readouts.warnings``), ``rigd diagnose``
adds them to its notes.
"""

from __future__ import annotations

import numpy as np


def _linear_a(structure, theta) -> np.ndarray | None:
    base, th = structure, np.asarray(theta, float)
    while hasattr(base, "effect"):  # effect wrappers: their parameters come last
        base = base.base
    th = th[:len(base.names)]
    try:
        if hasattr(base, "full_abcd"):
            return np.asarray(base.full_abcd(th)[0], float)
        if hasattr(base, "continuous"):
            return np.asarray(base.continuous(th)[0], float)
    except (ValueError, np.linalg.LinAlgError):
        return None
    return None


def model_warnings(structure, theta) -> list[str]:
    """Sentences naming each unstable mode and each parameter at a bound (empty: none)."""
    out = []
    A = _linear_a(structure, theta)
    if A is not None and np.all(np.isfinite(A)):
        for lam in np.linalg.eigvals(A):
            if lam.real >= 0 and lam.imag >= 0:
                if lam.imag > 1e-9:
                    out.append(f"unstable mode: f_n = {abs(lam) / (2 * np.pi):.4g} Hz, "
                               f"zeta = {-lam.real / abs(lam):.3g} (its free response grows; "
                               "do not use this model for design or simulation)")
                else:
                    out.append(f"unstable real pole at {lam.real:.4g} rad/s (do not use "
                               "this model for design or simulation)")
    if hasattr(structure, "bounds"):
        lo, hi = (np.asarray(b, float) for b in structure.bounds())
        th = np.asarray(theta, float)
        if lo.shape == th.shape:
            for n, v, a, b in zip(structure.names, th, lo, hi):
                tol = 1e-6 * max(1.0, abs(v))
                if (np.isfinite(a) and v - a <= tol) or (np.isfinite(b) and b - v <= tol):
                    out.append(f"parameter {n} = {v:.4g} is at its bound "
                               f"[{a:.4g}, {b:.4g}]: the data ask for more than the structure "
                               "allows")
    return out
