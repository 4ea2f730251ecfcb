"""``hysteresis``: piezo hysteresis in the valves.

Signature: the (actuator) residual depends on the direction of motion — it is explained by
play (backlash) operators of the input, the elementary hysterons of a Prandtl–Ishlinskii
model, i.e. loops in the r–u plane. Extension: each input replaced by
u + Σ_m a_m (play_{w_m}(u) − u) with widths w_m fixed at fractions of the input's range and
the weights a_m fitted.

A two-level input cannot show it: the play operator of a two-level signal is an affine
function of the signal (a gain change), so the diagnosis asks for multi-level excitation.
"""

from __future__ import annotations

import numpy as np

from rigd.effects._signals import n_levels, play
from rigd.effects.base import CannotReveal, Context, Effect, dims, replace_inputs

WIDTHS = (0.05, 0.15, 0.35)  # play widths, fractions of the input's 1-99 % range


def hysterons(x: np.ndarray) -> list[np.ndarray]:
    lo, hi = np.percentile(x, [1, 99])
    span = max(hi - lo, 1e-12)
    return [play(np.ascontiguousarray(x), w * span) - x for w in WIDTHS]


class Hysteresis(Effect):
    name = "hysteresis"
    level = "input"
    submodels = ("actuator", "generic")
    physics = "hysteresis (piezo valves): the response depends on the direction of motion"

    def reveal(self, ctx: Context) -> CannotReveal | None:
        lv = min(n_levels(ctx.u[:, j]) for j in range(ctx.nu))
        if lv <= 2:
            return CannotReveal(self.name, f"the input has only {lv} levels: hysteresis looks "
                                "like a gain change", "re-run with multi-level excitation "
                                "(multi-level PRBS or a slow triangle)", ctx.submodel)
        return None

    def regressors(self, ctx):
        regs = []
        for j in range(ctx.nu):
            for h in hysterons(ctx.u[:, j]):
                regs.append(ctx.through_model(h, j))
        return regs

    def explain(self, ctx, sig):
        du = np.gradient(ctx.u, axis=0)
        r = ctx.residual
        up, dn = du > 0, du < 0
        diffs = [float(np.mean(r[up[:, j], j if j < ctx.ny else 0]) -
                       np.mean(r[dn[:, j], j if j < ctx.ny else 0]))
                 if up[:, j].any() and dn[:, j].any() else 0.0 for j in range(ctx.nu)]
        j = int(np.argmax(np.abs(diffs)))
        ev = {"up_minus_down": {ctx.label(i, "in"): d for i, d in enumerate(diffs)}}
        return (f"the residual on {ctx.label(j if j < ctx.ny else 0)} is {diffs[j]:+.3g} higher "
                f"when {ctx.label(j, 'in')} rises than when it falls: hysteresis (loops in the "
                f"r–u plane, piezo valves); play operators explain {100 * sig.score:.0f} % of "
                f"the residual", ev)

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        _, nu = dims(base)
        return [f"hyst_a{m}_{j}" for j in range(nu) for m in range(len(WIDTHS))]

    def warm_start(self, ctx, sig):
        return np.asarray(sig.beta, float)

    def simulate_with(self, sim, theta_e, data, base):
        u = np.asarray(data.inputs, float)
        a = np.asarray(theta_e, float).reshape(u.shape[1], len(WIDTHS))
        v = u.copy()
        for j in range(u.shape[1]):
            if np.any(a[j]):
                for m, h in enumerate(hysterons(u[:, j])):
                    v[:, j] += a[j, m] * h
        return sim(replace_inputs(data, v))
