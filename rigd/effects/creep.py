"""``creep``: slow piezo creep after steps, acting on the drive inside the valve loops.

Physics (docs/plant.md): the stack follows a step of its drive by a fast part and a slow
drift, modelled as first-order lags adding fractions of the drive, v' = v + Σ_m f_m L_τm(v),
L_τ = 1/(τ s + 1). Through the PD-closed valve loop (rigd.effects._drive)

    u = H_a(s) · (r + Σ_m c_m · (L_τm(x) − x))                        (Eqs. 8–10 plus creep)

with x = (v_+ − v_−)/2 the recorded drives of the axis' valve pair (Eq. 1; the input itself
when the record has no drives) and c_m ≈ f_m/(kff + kp) the loop-suppressed fractions (the
static part c_m·x, ≈ c_m·r, is absorbed by the base gain, so the prefilters' offset removal
leaves it unbiased). Two lags; the weights c_m per axis and the time constants τ_1 < τ_2
(shared by the axes, as the valves' material) are fitted with the rest.

Signature: after each step the output keeps drifting exponentially toward its final value
while the input holds still (rate-dependent: a fast back-and-forth leaves no trace; hysteresis
instead keeps a direction-dependent offset that does not decay). The regressors are the
model-filtered lags for the best (τ_1, τ_2) of a small grid (estimation part).

A record whose input never holds still long enough cannot show it: the diagnosis asks for
steps held for tens of ms or more (config/experiments/multilevel_slow.yaml).
"""

from __future__ import annotations

import numpy as np

from rigd.effects import numbers as N
from rigd.effects._drive import drive_note, valve_pairs
from rigd.effects._signals import lag1
from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.signature import SignatureFit, signature_fit
from rigd.ident.iddata import replace_inputs

#: (τ_1, τ_2) pairs tried by the signature, s
GRID = ((0.005, 0.05), (0.01, 0.1), (0.02, 0.2), (0.05, 0.5), (0.1, 1.0), (0.01, 0.5))
TAU_BOUNDS = (0.001, 10.0)
#: the input must hold still this long, s, on at least HOLD_SHARE of the record
MIN_HOLD_S = 0.02
HOLD_SHARE = 0.3


def drives(data) -> np.ndarray:
    """(n, nu) drive per axis, (v_+ − v_−)/2 from the record, else the input; from 0 at t = 0."""
    pairs = valve_pairs(data)
    if pairs is None:
        x = np.asarray(data.inputs, float)
    else:
        x = np.stack([0.5 * (p - m) for p, m in pairs], axis=1)
    return x - x[:1]


def creep_terms(x: np.ndarray, taus, fs: float) -> list[np.ndarray]:
    """L_τ(x) − x for each τ (lags starting at rest; no offset: the prefilters removed the
    mean of r and u, and the base model's gain absorbs the creep's extra static gain)."""
    return [lag1(x, t, fs) - x for t in taus]


def initial_terms(n: int, taus, fs: float) -> list[np.ndarray]:
    """exp(−t/τ) for each τ: the creep states' own decay when the record starts mid-creep
    (after a step before the record began, or the valves settling at start-up)."""
    t = np.arange(n) / fs
    return [np.exp(-t / max(tau, 1e-9)) for tau in taus]


def held_share(u: np.ndarray, fs: float, min_hold_s: float = MIN_HOLD_S) -> float:
    """Share of samples inside stretches where the input holds still ≥ ``min_hold_s``."""
    u = np.asarray(u, float)
    span = max(float(np.ptp(u)), 1e-300)
    moving = np.r_[True, np.abs(np.diff(u)) > 1e-3 * span]
    starts = np.flatnonzero(moving)
    lengths = np.diff(np.r_[starts, u.shape[0]])
    return float(np.sum(lengths[lengths >= min_hold_s * fs]) / u.shape[0])


class Creep(Effect):
    name = "creep"
    level = "input"
    submodels = ("actuator", "generic")
    physics = "slow creep after steps (piezo valves)"

    def reveal(self, ctx: Context) -> CannotReveal | None:
        share = min(held_share(ctx.u[:, j], ctx.fs) for j in range(ctx.nu))
        if share < HOLD_SHARE:
            return CannotReveal(self.name, f"the input seldom holds still: only "
                                f"{100 * share:.0f} % of the record lies in holds of "
                                f"≥ {1000 * MIN_HOLD_S:.0f} ms, too short to see a slow drift",
                                "re-run with steps held for 0.05–0.5 s (multi-level with "
                                "long holds, config/experiments/multilevel_slow.yaml)",
                                ctx.submodel)
        return None

    # --- signature ---------------------------------------------------------------------
    def _regs(self, ctx: Context, taus) -> list[np.ndarray]:
        """Per axis j: the two creep terms of its drive, then the two initial-state decays."""
        x = drives(ctx.data)
        n = x.shape[0]
        return [ctx.through_model(h, j) for j in range(ctx.nu)
                for h in (*creep_terms(x[:, j], taus, ctx.fs), *initial_terms(n, taus, ctx.fs))]

    def signature(self, ctx: Context) -> SignatureFit:
        best, best_t = None, GRID[0]
        for taus in GRID:
            s = signature_fit(ctx, self._regs(ctx, taus))
            if best is None or s.score_est > best.score_est:
                best, best_t = s, taus
        best.extra = {"tau_s": list(best_t), "operator_input": drive_note(ctx.data)}
        return best

    def regressors(self, ctx):
        return self._regs(ctx, GRID[0])

    def explain(self, ctx, sig):
        taus = sig.extra.get("tau_s", list(GRID[0]))
        c = np.asarray(sig.beta, float).reshape(ctx.nu, 2 * len(taus))[:, :len(taus)]
        j, m = np.unravel_index(np.argmax(np.abs(c)), c.shape)
        ev = {"weights": {ctx.label(i, "in"): c[i].tolist() for i in range(ctx.nu)},
              "time_constants_ms": [1000 * t for t in taus],
              "dominant_time_constant_ms": 1000 * taus[m]}
        size = (f"{N.share(abs(c[j, m]))} of the step" if abs(c[j, m]) <= 1.0 else
                "larger than the step itself, implausible for creep")
        return (f"after each step of {ctx.label(j, 'in')} the response keeps drifting toward "
                f"its final value for ~{N.freqs([1000 * taus[m]])[0]} ms while the input "
                f"holds still (lags of {sig.extra.get('operator_input', 'the input')}, "
                f"{size}): {'piezo creep' if N.is_rotor(ctx) else 'creep (slow drift after steps)'}"
                f"; they explain {N.share(sig.score)} of the residual", ev)

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        _, nu = dims(base)
        # weights of the two lags per axis, the creep states at the start of the record
        # (V of drive; 0 = the record starts in creep equilibrium), the two time constants
        return ([f"creep_c{m}_{j}" for j in range(nu) for m in range(2)]
                + [f"creep_init{m}_{j}" for j in range(nu) for m in range(2)]
                + ["creep_tau1_s", "creep_tau2_s"])

    def theta0_effect(self, base, data):
        _, nu = dims(base)
        return np.concatenate([np.zeros(4 * nu), GRID[3]])

    def param_bounds(self, base):
        _, nu = dims(base)
        return (np.concatenate([np.full(4 * nu, -np.inf), [TAU_BOUNDS[0]] * 2]),
                np.concatenate([np.full(4 * nu, np.inf), [TAU_BOUNDS[1]] * 2]))

    def warm_start(self, ctx, sig):
        b = np.asarray(sig.beta, float).reshape(ctx.nu, 4)
        return np.concatenate([b[:, :2].ravel(), b[:, 2:].ravel(),
                               sig.extra.get("tau_s", list(GRID[3]))])

    def simulate_with(self, sim, theta_e, data, base):
        u = np.asarray(data.inputs, float)
        nu = u.shape[1]
        te = np.asarray(theta_e, float)
        c = te[:2 * nu].reshape(nu, 2)
        c_init = te[2 * nu:4 * nu].reshape(nu, 2)
        taus = te[4 * nu:4 * nu + 2]
        if not (np.any(c) or np.any(c_init)):
            return sim(data)
        x = drives(data)
        fs = float(data.fs)
        v = u.copy()
        decay = initial_terms(u.shape[0], taus, fs)
        for j in range(nu):
            for m, h in enumerate(creep_terms(x[:, j], taus, fs)):
                v[:, j] += c[j, m] * h + c_init[j, m] * decay[m]
        return sim(replace_inputs(data, v))
