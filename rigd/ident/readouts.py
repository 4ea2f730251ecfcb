"""Every read-out of a model's linear dynamics, computed from its :class:`LinearPart` alone.

Poles, modes (natural frequency f_n in Hz and damping ratio ζ), real poles and their time
constants, integrators, the static (DC) gain of the *whole* model (every state, feedthrough
included) and the per-input delays. ``rigd identify``/``compare``/``diagnose`` print these
and the model files store them (``readouts``); nothing else computes them.

Integrators: a pole within ``INTEGRATOR_TOL`` (relative to the fastest pole, or of the
sample rate) of 0 is an integrator; the static gain of an output an integrator reaches is
infinite (``None`` in JSON, "∞" in print) and its *integrating* gain (the slope per unit
input, output units per input unit per second) is reported instead.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.ident.model import LinearPart

#: |pole| below this fraction of the scale (fastest pole, or the rate in rad/s) is an integrator
INTEGRATOR_TOL = 1e-9


def poles(lp: LinearPart) -> np.ndarray:
    """Continuous poles (rad/s), complex, sorted by magnitude."""
    A = np.asarray(lp.A, float)
    if A.size == 0:
        return np.zeros(0, complex)
    lam = np.linalg.eigvals(A)
    return lam[np.argsort(np.abs(lam), kind="stable")]


def _scale(lp: LinearPart, lam: np.ndarray) -> float:
    ref = float(np.max(np.abs(lam))) if lam.size else 0.0
    if lp.fs:
        ref = max(ref, 2 * np.pi * float(lp.fs))
    return ref or 1.0


def integrator_count(lp: LinearPart) -> int:
    """Number of poles at 0 (explicit integrators and poles within the tolerance)."""
    lam = poles(lp)
    return int(np.sum(np.abs(lam) <= INTEGRATOR_TOL * _scale(lp, lam)))


def modes(lp: LinearPart) -> list[dict[str, Any]]:
    """One dict per complex pair (``f_n_hz``, ``zeta``), then per real pole (``pole_rad_s``,
    ``time_constant_s``), then per integrator (``integrator: True``)."""
    lam = poles(lp)
    tol = INTEGRATOR_TOL * _scale(lp, lam)
    out = []
    for v in lam:
        if v.imag > 1e-9 * max(abs(v), 1e-300) and abs(v) > tol:
            out.append({"f_n_hz": float(abs(v) / (2 * np.pi)), "zeta": float(-v.real / abs(v))})
    for v in sorted(v.real for v in lam if abs(v.imag) <= 1e-9 * max(abs(v), 1e-300)
                    and abs(v) > tol):
        out.append({"pole_rad_s": float(v), "time_constant_s": float(-1.0 / v)})
    out += [{"integrator": True}] * int(np.sum(np.abs(lam) <= tol))
    return out


def resonances_hz(lp: LinearPart) -> list[float]:
    """Natural frequencies (Hz) of the complex pairs, ascending."""
    return sorted({round(m["f_n_hz"], 6) for m in modes(lp) if "f_n_hz" in m})


def static_gain(lp: LinearPart) -> tuple[np.ndarray, np.ndarray]:
    """(G0, Gi): static gain D − C A⁻¹ B (ny, nu), ``inf`` where an integrator is reached,
    and the integrating gain (slope per unit input, 1/s; 0 where none) of the whole model.

    Computed on the modal decomposition when A has poles at 0 (the integrating part is the
    residue at s = 0), else by a linear solve.
    """
    A, B = np.asarray(lp.A, float), np.asarray(lp.B, float)
    C, D = np.asarray(lp.C, float), np.asarray(lp.D, float)
    ny, nu = D.shape
    if A.size == 0:
        return D.copy(), np.zeros((ny, nu))
    lam = poles(lp)
    tol = INTEGRATOR_TOL * _scale(lp, lam)
    if not np.any(np.abs(lam) <= tol):
        try:
            return D - C @ np.linalg.solve(A, B), np.zeros((ny, nu))
        except np.linalg.LinAlgError:
            pass
    w, V = np.linalg.eig(A)
    try:
        W = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return np.full((ny, nu), np.nan), np.full((ny, nu), np.nan)
    G0 = D.astype(complex)
    Gi = np.zeros((ny, nu), complex)
    for k, lk in enumerate(w):
        R = np.outer(C @ V[:, k], W[k] @ B)   # residue of 1/(s − λ_k)
        if abs(lk) <= tol:
            Gi += R
        else:
            G0 -= R / lk
    Gi = Gi.real
    scale = max(float(np.max(np.abs(Gi))), 1e-300)
    integrating = np.abs(Gi) > 1e-9 * scale
    G0 = np.where(integrating, np.inf, G0.real)
    return G0, np.where(integrating, Gi, 0.0)


def _json_matrix(M: np.ndarray) -> list[list[float | None]]:
    return [[float(v) if np.isfinite(v) else None for v in row] for row in np.atleast_2d(M)]


def linear_readouts(lp: LinearPart) -> dict[str, Any]:
    """The read-outs of a linear part, as a model file stores them (JSON-ready).

    Keys: ``modes`` (see :func:`modes`), ``static_gain`` (ny × nu; ``None`` where an
    integrator is reached), ``integrators`` (count), ``integrating_gain`` (only with
    integrators), ``delays_samples`` (per input) and ``states``.
    """
    G0, Gi = static_gain(lp)
    out: dict[str, Any] = {"modes": modes(lp), "static_gain": _json_matrix(G0),
                           "integrators": integrator_count(lp),
                           "delays_samples": [int(d) for d in lp.delays], "states": lp.nx}
    if out["integrators"]:
        out["integrating_gain"] = _json_matrix(Gi)
    return out
