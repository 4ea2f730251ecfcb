"""Generic models of the right order: the n-DOF mechanical base plus parallel modes.

A record from another rig may carry more modes than it has outputs (a flexible structure
measured at one point): the generic mechanical structure (one DOF per output,
:func:`rigd.ident.greybox.mechanical.generic_structure`) with ``m`` parallel modes
(``base.with_modes(m)``, :mod:`rigd.ident.greybox.parallel`), each ω²/(s² + 2ζω s + ω²) from every
input to every output with its own gains (``modeK_f_hz``, ``modeK_zeta``,
``modeK_g_<in>_<out>``).

:func:`choose_order` picks the number of modes from the data:

1. fit the base (one mode per output) by output error on the estimation part;
2. repeat: a subspace estimate (:mod:`rigd.ident.lti.subspace`) of the dynamics left in
   the residual u → y − ŷ gives the candidate mode(s) away from the model's modes; their
   gains by linear least squares; the whole model refined by output error;
3. keep the mode when it raises the *validation* fit by at least ``MIN_GAIN`` points — the
   practical-significance rule of the diagnosis (``rigd.diagnose.engine.MIN_FIT_GAIN``) —
   and stop at the first mode that does not (or at ``max_modes``).

Frequencies are bounded relative to the record (two periods in the estimation part ..
0.95·Nyquist), damping to 0 < ζ < 1: nothing depends on the units or on the rate given.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.ident.figures import mean_fit
from rigd.ident.thresholds import MIN_FIT_GAIN, MODE_SEPARATION

#: validation fit (points) a mode must add to be kept: the practical significance
MIN_GAIN = MIN_FIT_GAIN
#: most modes in all (base DOFs included) tried by ``order="auto"``
MAX_MODES = 6
#: relative distance from an existing mode for a candidate to count as new
MIN_SEPARATION = MODE_SEPARATION


# --------------------------------------------------------------------------------------
# order selection
# --------------------------------------------------------------------------------------
@dataclass
class OrderChoice:
    """The chosen structure, its parameters and the validation fit of each order tried."""

    structure: Any
    theta: np.ndarray
    modes: int
    fits: dict[int, float] = field(default_factory=dict)
    reason: str = ""
    #: ``--order`` as asked (a number of states, 2 per mode, or ``auto``)
    asked: str | int = "auto"
    #: per-input delays (samples): the mechanical model has none
    delays: list[int] = field(default_factory=list)
    family: str = "mechanical"

    @property
    def states(self) -> int:
        """States of the model: 2 per mode (x = [p, ṗ] and each parallel mode's pair)."""
        return 2 * int(self.modes)

    def describe(self) -> str:
        tried = ", ".join(f"{k}: {v:.2f} %" for k, v in sorted(self.fits.items()))
        return (f"mechanical n-DOF model, {self.states} states ({self.modes} mode(s); "
                f"validation fit by number of modes: {tried}; {self.reason})")

    def to_json(self) -> dict[str, Any]:
        return {"modes": self.modes, "family": self.family, "states": self.states,
                "delays_samples": list(self.delays), "asked": self.asked,
                "validation_fit_by_modes":
                {str(k): round(v, 3) for k, v in sorted(self.fits.items())},
                "reason": self.reason}


def _fit_pct(y, yh):
    return mean_fit(y, yh)


def candidate_mode(u, r, fs, exclude_hz, hold="foh"):
    """(f_hz, zeta, g (nu, ny)) of the mode that explains most of the residual ``r`` (n, ny)
    given the inputs ``u`` (n, nu): subspace estimates of orders 2..6 of u → r, modes away
    from ``exclude_hz``, gains by least squares; None when none is found."""
    from rigd.ident.lti.subspace import continuous_modes, dynamics_matrices
    from rigd.lti import resonator

    cands = []
    # one decomposition per distinct horizon, A alone (the gains come below)
    tries = [(order, hz) for order in (2, 4, 6) for hz in (None, 4 * order + 10)]
    for A in dynamics_matrices(u, r, tries):
        if A is None:
            continue
        for f, z in continuous_modes(A, fs):
            if all(abs(f - e) > MIN_SEPARATION * e for e in exclude_hz):
                cands.append((f, z))
    best, best_ss = None, 0.0
    r0 = r - r.mean(0)
    tot = float(np.sum(r0 ** 2))
    for f, z in cands:
        regs = np.column_stack([resonator(u[:, j] - u[:, j].mean(), f, z, fs)[0]
                                for j in range(u.shape[1])])
        g, *_ = np.linalg.lstsq(regs, r0, rcond=None)
        ss = tot - float(np.sum((r0 - regs @ g) ** 2))
        if ss > best_ss:
            best, best_ss = (f, z, g), ss
    return best


def _unresolved(st, theta) -> str:
    """'' when every pair of modes is resolvable, else which pair is not: closer than
    ``MIN_SEPARATION`` (relative) or with overlapping half-power bands (|f_i − f_j| ≤
    ζ_i f_i + ζ_j f_j). Each parallel mode counts once: its realisation repeats its pole
    pair once per input (``ParallelModes.blocks``), which is one mode, not several."""
    lam = np.linalg.eigvals(st.continuous(theta)[0])
    modes = [(abs(v) / (2 * np.pi), -v.real / abs(v)) for v in lam if v.imag > 1e-9]
    modes = sorted(modes + [(f, z) for f, z, _ in st.modes_of(theta)])
    for (f1, z1), (f2, z2) in zip(modes, modes[1:]):
        if f2 - f1 < MIN_SEPARATION * f2 or f2 - f1 <= z1 * f1 + z2 * f2:
            return f"the modes at {f1:.4g} Hz and {f2:.4g} Hz overlap"
    return ""


def choose_order(base, data, est: slice, val: slice, order: str | int = "auto",
                 base_theta: np.ndarray | None = None, max_nfev: int | None = None,
                 max_modes: int = MAX_MODES) -> OrderChoice:
    """Base structure with the number of modes chosen from the data (module docstring).

    Parameters
    ----------
    base : MechanicalStructure
        Generic base (one DOF per output).
    data : IdData
        The whole (prefiltered) record; ``est``/``val`` the estimation/validation parts.
    order : "auto" or int
        ``auto``, or the number of modes (≥ the number of outputs) to fit.
    base_theta : ndarray, optional
        The base already fitted on the estimation part (skips that fit).
    """
    from rigd.ident.pem import fit

    d_est = data.slice(est.start, est.stop)
    yv = data.y[val]
    if base_theta is None:
        base_theta = fit(base, d_est, method="oe", max_nfev=max_nfev).theta
    st, th = base, np.asarray(base_theta, float)
    fits = {base.n: _fit_pct(yv, np.asarray(base.simulate(th, data))[val])}
    want = None if order == "auto" else int(order)
    if want is not None and want < base.n:
        raise ValueError(f"order {want} is below the {base.n} mode(s) of the base structure "
                         f"(one per output)")
    top = want if want is not None else max_modes
    reason = "no further mode found in the residual"
    fs = float(data.fs)
    for m in range(1, top - base.n + 1):
        yh_est = np.asarray(st.simulate(th, d_est))
        r = d_est.y - yh_est
        have = (st.resonances_hz(th) if st.m
                else [md["f_n_hz"] for md in base.modes(th) if "f_n_hz" in md])
        cand = candidate_mode(d_est.u, r, fs, have, base.hold)
        if cand is None:
            reason = "no further mode found in the residual"
            break
        f, z, g = cand
        new = base.with_modes(m)
        new.set_record(fs, d_est.n)
        th0 = np.concatenate([th, [f, z], np.asarray(g, float).ravel(), np.zeros(2 * base.n)])
        lo, hi = new.bounds()
        th0 = np.clip(th0, lo, hi)
        try:
            res = fit(new, d_est, method="oe", theta0=th0, max_nfev=max_nfev)
        except (np.linalg.LinAlgError, ValueError):
            reason = "refit with one more mode failed"
            break
        yh = np.asarray(new.simulate(res.theta, data))
        if not np.all(np.isfinite(yh)):
            reason = "the model with one more mode is unstable"
            break
        fv = _fit_pct(yv, yh[val])
        fits[base.n + m] = fv
        clash = _unresolved(new, res.theta)
        if clash:
            reason = (f"one more mode is not a separate mode: after the refit {clash} "
                      "(what it fits is not a structural mode)")
            break
        if want is None and fv - fits[base.n + m - 1] < MIN_GAIN:
            reason = (f"one more mode adds {fv - fits[base.n + m - 1]:.2f} points "
                      f"(< {MIN_GAIN})")
            break
        st, th = new, res.theta
    else:
        reason = (f"order {want} asked" if want is not None else
                  f"the most modes tried ({max_modes})")
    modes = base.n + st.m
    return OrderChoice(st, th, modes, fits, reason)
