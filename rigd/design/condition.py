"""The design model made well posed for H∞ synthesis.

The linear blocks of the effects a diagnosis names (``ModelFile.plant(effects=True)``) can put
poles where the design at the loop rate cannot see them but the synthesis still has to solve
for them: a lag of a few µs (``actuator_dynamics``, ``extra_dynamics`` refitted to soak up
something fast) is a real pole one to three decades above the Nyquist frequency. In the
generalized plant (solved in the time unit 1/(2π·100 Hz)) such a pole makes the Riccati
equations stiff (measured: G_p with a 10 µs lag on each input did not finish SB10AD in 8 min
at load 12, the plain G_p took ≈ 1 min), and a mode the outputs cannot see on or near the
imaginary axis makes SB10AD's rank test of [A − jωI, B₂; C₁, D₁₂] fail. Nothing the discrete
controller does can act on a pole at ≥ 2π·fs: it leaves a phase lag under 15 % of π at the
Nyquist frequency and none in the damping band.

:func:`condition` returns the plant the synthesis runs on: its states split (real Schur form,
ordered, then a Sylvester equation) into the part with poles below ``fast_factor``·2π·fs and
the rest, the fast part residualised (its DC gain kept — a series lag becomes a unit gain)
and, as the H∞ problem needs a strictly proper plant, its remaining direct term dropped; then
states that do not reach the output or cannot be reached from the input removed (a minimal
realization). What was done is returned beside it, with the largest relative change of the
frequency response up to ``fs``/10 (:data:`CHECK_SHARE`), and the synthesis refuses
(InputError) when
that change is over ``max_change``: the fast part then matters and the model is not one to
design on at this rate.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.errors import InputError

#: Poles above this multiple of 2π·fs (rad/s) are residualised before synthesis.
FAST_FACTOR = 1.0
#: Largest relative change of σ̄(G) up to ``fs``/10 the conditioning may cause.
MAX_CHANGE = 0.1
#: The change is measured up to this share of ``fs`` (500 Hz at 5 kHz: where W_u rolls the
#: controller off; above it the loop has no authority by design).
CHECK_SHARE = 0.1


def _split(A, B, C, w_max: float):
    """(slow (A, B, C), fast (A, B, C)) of a block-diagonalised realization: poles with
    |λ| ≤ ``w_max`` in the slow part."""
    from scipy.linalg import schur, solve_sylvester

    T, Z, n_slow = schur(A, output="real", sort=lambda re, im: np.hypot(re, im) <= w_max)
    A11, A12, A22 = T[:n_slow, :n_slow], T[:n_slow, n_slow:], T[n_slow:, n_slow:]
    X = solve_sylvester(A11, -A22, -A12)          # A11 X − X A22 = −A12
    Bz, Cz = Z.T @ B, C @ Z
    B1 = Bz[:n_slow] - X @ Bz[n_slow:]
    C2 = Cz[:, n_slow:] + Cz[:, :n_slow] @ X
    return (A11, B1, Cz[:, :n_slow]), (A22, Bz[n_slow:], C2)


def condition(G, fs_hz: float, *, fast_factor: float = FAST_FACTOR,
              max_change: float = MAX_CHANGE) -> tuple[Any, dict]:
    """(G_c, info): the continuous plant ``G`` (python-control StateSpace, D = 0) with its
    poles above ``fast_factor``·2π·``fs_hz`` rad/s residualised and its non-minimal states
    removed (module docstring).

    Returns
    -------
    G_c : control.StateSpace
        Strictly proper, ``G``'s inputs and outputs.
    info : dict
        ``states`` (before, after), ``fast_poles_hz`` (|λ|/2π of the residualised poles),
        ``removed_nonminimal`` (states), ``change`` (max over f ≤ fs/10 of
        σ̄(G_c − G)/σ̄(G)).

    Raises
    ------
    InputError
        When the change is over ``max_change``, or ``G`` is not finite.
    """
    import control

    from rigd.design.robustness import freq_response

    A, B, C = (np.asarray(getattr(G, k), float) for k in "ABC")
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B)) and np.all(np.isfinite(C))):
        raise InputError("the design model has non-finite entries", "model")
    n0 = A.shape[0]
    w_max = fast_factor * 2 * np.pi * fs_hz
    lam = np.linalg.eigvals(A) if n0 else np.zeros(0)
    fast = lam[np.abs(lam) > w_max]
    Gc = G
    if fast.size:
        (A1, B1, C1), (A2, B2, C2) = _split(A, B, C, w_max)
        # residualised fast part: its DC gain −C2 A2⁻¹ B2 (a direct term), dropped below
        Gc = control.ss(A1, B1, C1, np.zeros((C.shape[0], B.shape[1])))
    n1 = Gc.nstates
    Gm = Gc.minreal() if n1 else Gc
    if Gm.nstates == n1:        # nothing to remove: keep the realization as it was
        Gm = Gc
    Gm = control.ss(Gm.A, Gm.B, Gm.C, np.zeros_like(np.asarray(Gm.D, float)))
    f = np.geomspace(1.0, CHECK_SHARE * fs_hz, 300)
    R, Rc = freq_response(G, f), freq_response(Gm, f)
    num = np.linalg.svd(Rc - R, compute_uv=False)[:, 0]
    den = np.linalg.svd(R, compute_uv=False)[:, 0]
    change = float(np.max(num / np.maximum(den, 1e-300)))
    info = {"states": [int(n0), int(Gm.nstates)],
            "fast_poles_hz": sorted(float(v) for v in np.abs(fast) / (2 * np.pi)),
            "removed_nonminimal": int(n1 - Gm.nstates), "change": change}
    if change > max_change:
        poles = ", ".join(f"{v:.3g}" for v in info["fast_poles_hz"]) or "none"
        raise InputError(
            f"the design model changes by {change:.0%} up to {CHECK_SHARE * fs_hz:.0f} Hz when "
            f"its poles above {w_max / (2 * np.pi):.0f} Hz ({poles} Hz) are residualised and "
            f"its {info['removed_nonminimal']} non-minimal states removed: it has dynamics "
            f"the synthesis cannot handle that matter at the loop rate {fs_hz:g} Hz", "model")
    return Gm, info
