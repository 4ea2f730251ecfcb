"""``actuator_dynamics``: valve dynamics left out of the model.

Posed as in the paper's split (§4): the bearing model fed with the valve *references* r
instead of the measured valve positions u misses the closed-loop valve dynamics, Eq. 8,
H_a(s) = 1 / ((s/p1 + 1)(s/p2 + 1)) per lumped valve pair.

Signature: the residual is explained by the model response to the derivative of each input
(the first-order term of H_a − 1 = −(1/p1 + 1/p2) s + ...). Extension: each input passed
through H_a with its two time constants τ = 1/p fitted (τ = 0: no dynamics).
"""

from __future__ import annotations

import numpy as np

from rigd.effects import numbers as N
from rigd.effects._linear import lag_block, series_inputs
from rigd.effects._signals import derivative, lag1
from rigd.effects.base import Effect, dims
from rigd.effects.context import Context

#: longest lag time constant, samples (relative to the record's rate: 50 ms at the rig's
#: 5 kHz; rigd.effects.scales)
TAU_MAX_SAMPLES = 250.0
#: a fitted lag below this (samples) is not called actuator dynamics (as ``delay``)
MIN_TAU_SAMPLES = 0.5


class ActuatorDynamics(Effect):
    name = "actuator_dynamics"
    sites = ("input",)
    submodels = ("bearing", "generic")
    physics = "valve (actuator) dynamics missing between the commanded and the acting input"

    def regressors(self, ctx: Context):
        du = derivative(ctx.u, ctx.fs)
        return [ctx.through_model(du[:, j], j) for j in range(ctx.nu)]

    def explain(self, ctx, sig):
        taus = np.maximum(-np.asarray(sig.beta, float), 0.0)
        ev = {"time_constant_ms": {ctx.label(j, "in"): float(1000 * t)
                                   for j, t in enumerate(taus)}}
        j = int(np.argmax(taus)) if taus.size else 0
        tau = taus[j] if taus.size else 0.0
        fc = 1 / (2 * np.pi * tau) if tau > 0 else float("inf")
        ev["corner_hz"] = float(fc) if np.isfinite(fc) else None
        what = ("the valve dynamics are missing (is the model fed with references r instead "
                "of measured valve positions u?)" if N.is_rotor(ctx) else
                "dynamics between the recorded input and the force are missing (an actuator "
                "or sensor lag)")
        if not tau > 0:  # the derivative's component leads: no lag to report
            return (f"no lag of the response behind {ctx.label(j, 'in')} found (along the "
                    f"model response to the input derivative the residual leads, not lags); "
                    f"it explains {N.share(sig.score)} of the residual", ev)
        if tau * ctx.fs < MIN_TAU_SAMPLES:  # as implausible(): no lag this rate resolves
            return (f"the residual follows the model response to the input derivative on "
                    f"{ctx.label(j, 'in')} (explains {N.share(sig.score)} of it), as a lag of "
                    f"{N.duration(tau)} would: {tau * ctx.fs:.2g} samples, shorter than the "
                    f"{MIN_TAU_SAMPLES:g} sample a lag can be told by at this rate — the "
                    f"model misses some high-frequency phase (the hold, a sensor's filter), "
                    f"not a lag of its own", ev)
        return (f"the response lags the input like a low-pass of about {N.duration(tau)} "
                f"(corner {N.freq(fc, ctx.fs)}) on {ctx.label(j, 'in')}: {what}; "
                f"the residual follows the model response to the input derivative and "
                f"explains {N.share(sig.score)} of it", ev)

    def implausible(self, ctx, theta_e):
        # as a delay (rigd.effects.delay): lags all shorter than half a sample cannot be
        # told from unmodelled fast dynamics at the record's rate (relative: samples)
        tmax = float(np.max(np.asarray(theta_e, float))) if len(theta_e) else 0.0
        if tmax * ctx.fs >= MIN_TAU_SAMPLES:
            return None
        return (f"lags of at most {tmax * ctx.fs:.2f} samples improve the fit, but a lag "
                f"shorter than {MIN_TAU_SAMPLES:g} sample cannot be told from unmodelled fast "
                f"dynamics at {ctx.fs:g} Hz: the model misses some high-frequency phase lag, "
                "not an actuator lag")

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        _, nu = dims(base)
        return [f"act_tau{k}_{j}" for j in range(nu) for k in (1, 2)]

    def param_bounds(self, base):
        k = len(self.param_names(base))
        return np.zeros(k), np.full(k, np.inf)

    def param_typical(self, base, rec):
        return np.full(len(self.param_names(base)), 1.0 / rec.fs)  # one sample

    def record_bounds(self, base, rec):
        k = len(self.param_names(base))
        return np.zeros(k), np.full(k, TAU_MAX_SAMPLES / rec.fs)

    def warm_start(self, ctx, sig):
        tmax = TAU_MAX_SAMPLES / ctx.fs
        taus = np.maximum(-np.asarray(sig.beta, float), 0.05 / ctx.fs)
        return np.repeat(np.minimum(taus / 2, tmax / 2), 2)

    def linear(self, G, theta_e, base, fs):
        """1/((τ₁ s + 1)(τ₂ s + 1)) on each input."""
        t = np.asarray(theta_e, float).reshape(G.ninputs, 2)
        return series_inputs(G, [lag_block(t[j]) for j in range(G.ninputs)])

    def input_block(self, u, theta_e, data):
        """Two first-order lags 1/((τ₁ s + 1)(τ₂ s + 1)) on each input."""
        t = np.asarray(theta_e, float).reshape(u.shape[1], 2)
        fs = float(data.fs)
        return np.column_stack([lag1(lag1(u[:, j], t[j, 0], fs), t[j, 1], fs)
                                for j in range(u.shape[1])])
