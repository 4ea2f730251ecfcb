"""``creep``: slow piezo creep after steps, acting on the drive inside the valve loops.

Physics (docs/plant.md): the stack follows a step of its drive by a fast part and a slow
drift, modelled as first-order lags adding fractions of the drive, v' = v + Σ_m f_m L_τm(v),
L_τ = 1/(τ s + 1). Through the P(D)-closed valve loop (rigd.effects._drive), by superposition

    u = H_a(s) · (r + Σ_m c_m · L_τm(x))                              (Eqs. 8–10 plus creep)

with x = (v_+ − v_−)/2 the recorded drives of the axis' valve pair (Eq. 1; the input itself
when the record has no drives) and c_m ≈ f_m/(kff + kp) the loop-suppressed fractions. This
is exact for a closed loop: the drive contains the loop's feedback of u, so a form
c_m·(L(x) − x) that leaves the static part to the base gain is not (it fed back u). Each
creep input is offset-corrected like r and u (the mean over the prefilters' offset window,
rigd.ident.prefilter, removed), and two initial-state decays c0_m·e^(−t/τm) let the record
start mid-creep. Two lags; the weights c_m and c0_m per axis and the time constants
τ_1 < τ_2 (shared by the axes, as the valves' material) are fitted with the rest.

Time constants are relative to the record: the signature's grid spans 10 samples … a sixth
of the record (a slower lag cannot be told from a drift), no fixed seconds.

Signature: after each step the output keeps drifting exponentially toward its final value
(rate-dependent: a fast back-and-forth leaves a slow wander of the lag; hysteresis instead
keeps a direction-dependent offset that does not decay). The regressors are the
model-filtered lags for the best (τ_1, τ_2) of the grid (estimation part).

Can the record tell (rigd.effects.detectability): a creep of 10 % of the step (typical of
piezo stacks; the simulated plant's default is 18 % of the drive) (in the input's
units) at each time constant of the grid, simulated through the base model on the record's
own drives, must stay detectable after what the base model would absorb; else "cannot tell"
with the experiment (longer holds, a longer record).
"""

from __future__ import annotations

import weakref

import numpy as np

from rigd.effects import detectability as DT
from rigd.effects import numbers as N
from rigd.effects._drive import drive_note, valve_pairs
from rigd.effects._signals import lag1
from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.signature import SignatureFit, signature_fit
from rigd.ident.prefilter import PrefilterOptions

#: the grid of time constants: from this many samples ...
TAU_MIN_SAMPLES = 10.0
#: ... to this fraction of the record, geometrically spaced, this many values
TAU_MAX_SHARE = 1.0 / 6.0
N_TAUS = 7
#: (fast, slow) index pairs of the grid tried by the signature (ratios ≈ 8 and ≈ 60)
PAIRS = ((0, 2), (1, 3), (2, 4), (3, 5), (4, 6), (0, 4), (1, 5), (2, 6))
#: nominal creep for "can the record tell": this share of the step
NOMINAL_SHARE = 0.10


def tau_grid(n: int, fs: float) -> np.ndarray:
    """Time constants (s) the diagnosis tries on an n-sample record at fs: 10 samples … n/6
    samples, geometric; empty when the record is too short for any."""
    lo, hi = TAU_MIN_SAMPLES / fs, TAU_MAX_SHARE * n / fs
    if hi < 2 * lo:
        return np.zeros(0)
    return np.geomspace(lo, hi, N_TAUS)


def tau_pairs(n: int, fs: float) -> list[tuple[float, float]]:
    """(τ_1, τ_2) pairs of the signature's grid, s."""
    g = tau_grid(n, fs)
    return [(float(g[i]), float(g[j])) for i, j in PAIRS] if g.size else []


def offset_window(n: int) -> int:
    """Samples whose mean the prefilters remove as the offset (rigd.ident.prefilter)."""
    return min(PrefilterOptions().offset_samples, max(n // 4, 1))


def duration(t_s: float) -> str:
    """A time constant or record length for the text: ms below 1 s, else s (3 digits)."""
    return f"{1000 * t_s:.3g} ms" if t_s < 1.0 else f"{t_s:.3g} s"


def drives(data) -> np.ndarray:
    """(n, nu) drive per axis, (v_+ − v_−)/2 from the record, else the input; from 0 at t = 0."""
    pairs = valve_pairs(data)
    if pairs is None:
        x = np.asarray(data.inputs, float)
    else:
        x = np.stack([0.5 * (p - m) for p, m in pairs], axis=1)
    return x - x[:1]


def _demean(h: np.ndarray) -> np.ndarray:
    return h - np.mean(h[:offset_window(h.shape[0])])


def creep_terms(x: np.ndarray, taus, fs: float) -> list[np.ndarray]:
    """L_τ(x) for each τ (lags starting at rest on x[0]), offset-corrected like r and u."""
    return [_demean(lag1(x, t, fs)) for t in taus]


def initial_terms(n: int, taus, fs: float) -> list[np.ndarray]:
    """exp(−t/τ) for each τ, offset-corrected: the creep states' own decay when the record
    starts mid-creep (after a step before it began, or the valves settling at start-up)."""
    t = np.arange(n) / fs
    return [_demean(np.exp(-t / max(tau, 1e-300))) for tau in taus]


def nominal_weights(ctx: Context, x: np.ndarray) -> np.ndarray:
    """Per axis the creep weight c (input units per drive unit) of a creep of
    NOMINAL_SHARE of the step."""
    su = np.std(ctx.u, axis=0)
    sx = np.std(x, axis=0)
    return NOMINAL_SHARE * su / np.where(sx > 0, sx, 1.0)


class Creep(Effect):
    name = "creep"
    sites = ("input",)
    submodels = ("actuator", "generic")
    physics = "slow creep after steps (piezo valves)"
    linear_note = ("acts on the recorded valve drives inside the valve loops, not on the "
                   "model inputs")
    #: the last (data, τ) terms of :meth:`_terms` (the record held weakly)
    _memo: tuple | None = None

    def reveal(self, ctx: Context) -> CannotReveal | None:
        taus = tau_grid(ctx.n, ctx.fs)
        # the experiment is worded by rigd.diagnose.advice for the record's domain
        def cannot(why: str, partial: bool = False) -> CannotReveal:
            return CannotReveal(self.name, why, "", ctx.submodel, partial, code="slow",
                                evidence={"why": why})

        if taus.size == 0:
            return cannot(f"the record is too short ({ctx.n} samples) to tell a slow drift "
                          "from an offset")
        x = drives(ctx.data)
        c = nominal_weights(ctx, x)
        sigs = [sum(ctx.through_model(c[j] * creep_terms(x[:, j], [tau], ctx.fs)[0], j)
                    for j in range(ctx.nu)) for tau in taus]
        # the creep states' initial decays are free too: what they take up is no creep
        decays = [[ctx.through_model(initial_terms(ctx.n, [tau], ctx.fs)[0], j)
                   for j in range(ctx.nu)] for tau in taus]
        each = [DT.detectability(ctx, s, 4 * ctx.nu, z) for s, z in zip(sigs, decays)]
        ok = [d.detectable for d in each]
        if ok[-1] or DT.seen(ctx, self.signature(ctx)):
            return None
        ms = [duration(t) for t in taus]
        size = f"a creep of {100 * NOMINAL_SHARE:.0f} % of the step"
        record = f"{duration(ctx.n / ctx.fs)} record"
        if not any(ok):
            d = max(each, key=lambda e: e.fit_gain)
            return cannot(f"{size} with a time constant of {ms[0]}–{ms[-1]} would not show "
                          f"on this input (at best: {d.describe()}); slower creep cannot be "
                          f"told from a drift in a {record}")
        last = max(i for i, v in enumerate(ok) if v)
        d = each[-1]
        return cannot(f"{size} slower than ~{ms[last]} would not show on this input (at "
                      f"{ms[-1]}: {d.describe()}); faster creep would and is tested", True)

    # --- signature ---------------------------------------------------------------------
    def _regs(self, ctx: Context, taus) -> list[np.ndarray]:
        """Per axis j: the two creep terms of its drive, then the two initial-state decays."""
        x = drives(ctx.data)
        n = x.shape[0]
        return [ctx.through_model(h, j) for j in range(ctx.nu)
                for h in (*creep_terms(x[:, j], taus, ctx.fs), *initial_terms(n, taus, ctx.fs))]

    def _signature(self, ctx: Context) -> SignatureFit:
        grid = tau_pairs(ctx.n, ctx.fs) or [(1.0 / ctx.fs, ctx.n / ctx.fs)]
        best, best_t = None, grid[0]
        for taus in grid:
            s = signature_fit(ctx, self._regs(ctx, taus))
            if best is None or s.score_est > best.score_est:
                best, best_t = s, taus
        best.extra = {"tau_s": list(best_t), "operator_input": drive_note(ctx.data)}
        return best

    def regressors(self, ctx):
        grid = tau_pairs(ctx.n, ctx.fs) or [(1.0 / ctx.fs, ctx.n / ctx.fs)]
        return self._regs(ctx, grid[min(3, len(grid) - 1)])

    def explain(self, ctx, sig):
        taus = sig.extra.get("tau_s") or [1.0 / ctx.fs, ctx.n / ctx.fs]
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
        grid = tau_pairs(data.n, float(data.fs)) or [(1.0 / data.fs, data.n / data.fs)]
        return np.concatenate([np.zeros(4 * nu), grid[min(3, len(grid) - 1)]])

    def param_bounds(self, base):
        # without a record (record_bounds): time constants only positive; their range is
        # relative to the record (the grid, record_bounds, implausible()), never fixed seconds
        _, nu = dims(base)
        return (np.concatenate([np.full(4 * nu, -np.inf), [0.0, 0.0]]),
                np.full(4 * nu + 2, np.inf))

    def record_bounds(self, base, rec):
        """Time constants from half a sample to twice the fitted data's length."""
        _, nu = dims(base)
        return (np.concatenate([np.full(4 * nu, -np.inf), [0.5 / rec.fs] * 2]),
                np.concatenate([np.full(4 * nu, np.inf), [2.0 * rec.n / rec.fs] * 2]))

    def implausible(self, ctx, theta_e):
        taus = np.asarray(theta_e, float)[-2:]
        n_s = ctx.n / ctx.fs
        if np.min(taus) < 1.0 / ctx.fs:
            return (f"a creep time constant of {N.freqs([1000 * np.min(taus)])[0]} ms is "
                    "shorter than a sample: not a drift after steps")
        if np.max(taus) > n_s:
            return (f"a creep time constant of {N.freqs([np.max(taus)])[0]} s is longer than "
                    f"the record ({N.freqs([n_s])[0]} s): a drift the record cannot tell from "
                    "an offset or a trend")
        return None

    def warm_start(self, ctx, sig):
        b = np.asarray(sig.beta, float).reshape(ctx.nu, 4)
        return np.concatenate([b[:, :2].ravel(), b[:, 2:].ravel(), sig.extra["tau_s"]])

    def input_block(self, u, theta_e, data):
        """u + the creep terms of the drives (and the decay of a creep already under way)."""
        nu = u.shape[1]
        te = np.asarray(theta_e, float)
        c = te[:2 * nu].reshape(nu, 2)
        c_init = te[2 * nu:4 * nu].reshape(nu, 2)
        taus = te[4 * nu:4 * nu + 2]
        if not (np.any(c) or np.any(c_init)):
            return u
        terms, decay = self._terms(data, taus, u.shape[0])
        v = u.copy()
        for j in range(nu):
            for m, h in enumerate(terms[j]):
                v[:, j] += c[j, m] * h + c_init[j, m] * decay[m]
        return v

    def __getstate__(self):
        """Pickled (a shared diagnosis, a worker process) without the transient memo: it
        holds its record by a weak reference."""
        state = dict(self.__dict__)
        state.pop("_memo", None)
        return state

    def _terms(self, data, taus, n: int):
        """The lag terms per axis and the decay terms for (data, τ): the block is linear in
        the weights, so a fit's Jacobian columns for them (τ unchanged) reuse the terms of the
        last call instead of filtering the drives again (one entry: data and τ compared)."""
        key = (float(taus[0]), float(taus[1]), n, float(data.fs))
        memo = self._memo
        if memo is not None and memo[0]() is data and memo[1] == key:
            return memo[2], memo[3]
        x, fs = drives(data), float(data.fs)
        terms = [creep_terms(x[:, j], taus, fs) for j in range(x.shape[1])]
        decay = initial_terms(n, taus, fs)
        self._memo = (weakref.ref(data), key, terms, decay)
        return terms, decay
