"""Sanity checks of a fitted model: unstable modes and parameters at their bounds.

A fit can end with a mode of negative damping (its free response grows) or with a parameter
pressed against a bound (the data wanted more than the structure allows). Neither may be
used silently: :func:`model_warnings` returns one sentence per problem; ``rigd identify``
prints them and stores them in the model file (``readouts.warnings``), ``rigd diagnose``
adds them to its notes, ``rigd compare`` prints them again (:func:`file_warnings`);
``rigd design`` refuses a model with an unstable mode unless told ``--allow-flagged`` and
designs on one with a parameter at a bound with the warning printed and in its summary.
"""

from __future__ import annotations

import numpy as np


def _linear_a(structure, theta) -> np.ndarray | None:
    """Continuous A of the model's linear part (rigd.ident.model.linear_part_of)."""
    from rigd.ident.model import linear_part_of

    lp = linear_part_of(structure, theta)
    return None if lp is None else np.asarray(lp.A, float)


def unstable_modes(structure, theta) -> list[str]:
    """One sentence per unstable mode (or real pole) of the linear part at ``theta``."""
    out = []
    A = _linear_a(structure, theta)
    if A is not None and np.all(np.isfinite(A)):
        for lam in np.linalg.eigvals(A):
            if lam.real >= 0 and lam.imag >= 0:
                if lam.imag > 1e-9 * max(abs(lam), 1e-300):
                    out.append(f"unstable mode: f_n = {abs(lam) / (2 * np.pi):.4g} Hz, "
                               f"zeta = {-lam.real / abs(lam):.3g} (its free response grows; "
                               "do not use this model for design or simulation)")
                else:
                    out.append(f"unstable real pole at {lam.real:.4g} rad/s (do not use "
                               "this model for design or simulation)")
    return out


def at_bounds(structure, theta, at_bound=None, std=None) -> list[str]:
    """One sentence per parameter at one of its bounds.

    A parameter is at a bound when the optimiser found the bound active (``at_bound``, bool
    per parameter: :class:`rigd.ident.pem.FitResult` ``info["at_bound"]``), when it equals
    the bound to 1e-9 relative, or when its distance to the bound is below 1e-3 of its
    standard deviation ``std`` (the trust-region solver stops a hair inside a bound). No
    absolute tolerance: a small parameter of a record in metres is not "at" a bound of 0
    for being small.
    """
    lo, hi = (np.asarray(b, float) for b in structure.bounds())
    th = np.asarray(theta, float)
    if lo.shape != th.shape or hi.shape != th.shape:
        return []
    flags = np.zeros(th.shape, bool)
    if at_bound is not None and np.shape(at_bound) == th.shape:
        flags |= np.asarray(at_bound, bool)
    sd = (np.abs(np.asarray(std, float)) if std is not None and np.shape(std) == th.shape
          else np.zeros(th.shape))
    sd = np.where(np.isfinite(sd), sd, 0.0)
    out = []
    for i, (n, v, a, b) in enumerate(zip(structure.names, th, lo, hi)):
        hit = bool(flags[i])
        for c in (a, b):
            if np.isfinite(c):
                d = abs(v - c)
                hit |= d <= 1e-9 * max(abs(v), abs(c)) or d <= 1e-3 * sd[i]
        if hit:
            out.append(f"parameter {n} = {v:.4g} is at its bound [{a:.4g}, {b:.4g}]: the "
                       "data push it beyond what the structure allows, or do not need it")
    return out


def model_warnings(structure, theta, at_bound=None, std=None) -> list[str]:
    """Sentences naming each unstable mode and each parameter at a bound (empty: none).

    ``at_bound``, ``std``: the optimiser's active bounds and the standard deviations, if
    known (see :func:`at_bounds`).
    """
    return unstable_modes(structure, theta) + at_bounds(structure, theta, at_bound, std)


def is_unstable(warning: str) -> bool:
    """True for a warning about an unstable mode or pole (not a parameter at a bound)."""
    return "unstable" in warning.split("(", 1)[0]


def file_warnings(model) -> list[str]:
    """The warnings of every sub-model of a model file (``rigd.ident.modelfile.ModelFile``),
    each prefixed by its sub-model: those stored at identification (``readouts.warnings``)
    and the unstable modes its parameters give now (a file edited by hand or written before
    the check is caught too)."""
    out: list[str] = []
    for name, sm in model.submodels.items():
        stored = [str(w) for w in (sm.readouts or {}).get("warnings", []) or []]
        for w in stored + unstable_modes(sm.structure, sm.theta):
            line = f"{name}: {w}"
            if line not in out:
                out.append(line)
    return out
