"""``creep``: slow piezo creep after steps.

Signature: a low-frequency residual explained by slowly low-passed inputs: after each step the
response keeps drifting for tens to hundreds of ms. Extension: each input replaced by
u + Σ_m c_m (L_τm(u) − u), L_τ a first-order lag with τ_m fixed (10, 50, 250 ms); the sum of
lags approximates the logarithmic creep law, the weights c_m are fitted.
"""

from __future__ import annotations

import numpy as np

from rigd.effects._signals import band_power_share, lag1
from rigd.effects.base import CannotReveal, Context, Effect, dims, replace_inputs

TAUS_S = (0.01, 0.05, 0.25)


def creep_terms(x: np.ndarray, fs: float) -> list[np.ndarray]:
    return [lag1(x, t, fs) - x for t in TAUS_S]


class Creep(Effect):
    name = "creep"
    level = "input"
    submodels = ("actuator", "generic")
    physics = "slow creep after steps (piezo valves)"

    def reveal(self, ctx: Context) -> CannotReveal | None:
        dur = ctx.n / ctx.fs
        share = min(band_power_share(ctx.u[:, j], ctx.fs, 0.0, 10.0) for j in range(ctx.nu))
        if dur < 4 * TAUS_S[0] or share < 1e-3:
            return CannotReveal(self.name, f"the input holds no level long enough ({dur:.2f} s "
                                f"record, {100 * share:.2f} % of input power below 10 Hz)",
                                "re-run with steps held for at least 0.2 s (slow PRBS)",
                                ctx.submodel)
        return None

    def regressors(self, ctx):
        return [ctx.through_model(h, j) for j in range(ctx.nu)
                for h in creep_terms(ctx.u[:, j], ctx.fs)]

    def explain(self, ctx, sig):
        c = np.asarray(sig.beta, float).reshape(ctx.nu, len(TAUS_S))
        j, m = np.unravel_index(np.argmax(np.abs(c)), c.shape)
        ev = {"weights": {ctx.label(i, "in"): c[i].tolist() for i in range(ctx.nu)},
              "dominant_time_constant_ms": 1000 * TAUS_S[m]}
        return (f"after each step of {ctx.label(j, 'in')} the response keeps drifting for "
                f"~{1000 * TAUS_S[m]:.0f} ms ({100 * abs(c[j, m]):.0f} % of the step): piezo "
                f"creep; slow lags of the input explain {100 * sig.score:.0f} % of the "
                f"residual", ev)

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        _, nu = dims(base)
        return [f"creep_c{m}_{j}" for j in range(nu) for m in range(len(TAUS_S))]

    def warm_start(self, ctx, sig):
        return np.asarray(sig.beta, float)

    def simulate_with(self, sim, theta_e, data, base):
        u = np.asarray(data.inputs, float)
        c = np.asarray(theta_e, float).reshape(u.shape[1], len(TAUS_S))
        v = u.copy()
        fs = float(data.fs)
        for j in range(u.shape[1]):
            if np.any(c[j]):
                for m, h in enumerate(creep_terms(u[:, j], fs)):
                    v[:, j] += c[j, m] * h
        return sim(replace_inputs(data, v))
