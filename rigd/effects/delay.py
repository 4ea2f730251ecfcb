"""``delay``: transport delay valve → film force, sensor or computation latency.

Signature: the residual is explained by the model response to the input shifted by d samples
(scanned over d), i.e. the residual–input cross-correlation peaks at a positive lag and the
phase lag grows with frequency. On a generic record whose base fit has absorbed the delay
into its own lags (a second-order model takes a first-order plant's 3-sample delay into a
wrong damping and gain: its residual then barely correlates with the shift), the same scan
is made on the linearised refit (:mod:`rigd.effects.linearised`: the shift together with the
base's own sensitivities) when the plain one is not decisive. Extension: the input delayed
by a fitted d (fractional samples, linear interpolation); the size reported is the refit's
(:meth:`Delay.refitted_evidence`), the signature's first-order estimate only without a refit.
"""

from __future__ import annotations

import numpy as np

from rigd.effects import numbers as N
from rigd.effects._linear import delay_block, pade_order, series_inputs
from rigd.effects._signals import band_power_share, shift
from rigd.effects.base import Effect
from rigd.effects.context import CannotReveal, Context, Finding
from rigd.effects.linearised import joint_signature
from rigd.effects.signature import signature_fit
from rigd.ident.figures import fit_percent
from rigd.ident.model import base_of
from rigd.ident.thresholds import P_LEVEL

#: scan range of the signature, samples (relative to the record's rate: 4 ms at the rig's
#: 5 kHz loop; a longer lag is a dynamics the model misses, not a latency)
MAX_DELAY_SAMPLES = 20
MAX_SCAN = 40         # at most this many trial delays
#: a fitted delay below this (samples) is not called a transport delay: at the record's rate
#: it cannot be told from unmodelled fast dynamics (a higher-order valve or sensor response)
MIN_DELAY_SAMPLES = 0.5


class Delay(Effect):
    name = "delay"
    sites = ("input",)
    physics = "a transport delay between input and response"

    def _grid(self, ctx: Context) -> np.ndarray:
        dmax = MAX_DELAY_SAMPLES
        if dmax <= MAX_SCAN:
            return np.arange(1, dmax + 1, dtype=float)
        return np.unique(np.round(np.geomspace(1, dmax, MAX_SCAN)))

    def carried_by_base(self, ctx: Context) -> Finding | None:
        """A finding when the base model already delays its inputs (the general LTI and
        process families take a per-input delay in whole samples, chosen before their order:
        rigd.ident.lti.order): the delay is named from the base, not added."""
        base = base_of(ctx.structure)
        delays = [int(d) for d in base.delays]
        if not delays or max(delays) <= 0:
            return None
        fp = float(np.mean(fit_percent(ctx.y[ctx.val], ctx.yhat[ctx.val])))
        j = int(np.argmax(delays))
        ev = {"code": "delay.in_base", "delay_samples": float(delays[j]),
              "delay_ms": float(1000 * delays[j] / ctx.fs), "input": ctx.label(j, "in"),
              "delays_samples": delays, "hold": base.hold}
        # the words are the diagnosis' (rigd.diagnose.wording, from the code)
        return Finding(self.name, 0.0, True, "", ctx.submodel, 0.0, fp, ev)

    def reveal(self, ctx: Context) -> CannotReveal | None:
        share = min(band_power_share(ctx.u[:, j], ctx.fs, 0.05 * ctx.fs, ctx.fs / 2)
                    for j in range(ctx.nu))
        if share < 1e-4:
            # no power above 5 % of the sample rate: reason and experiment are worded for
            # the record's domain by rigd.diagnose.advice (code no_band)
            return CannotReveal(self.name, "", "", ctx.submodel, code="no_band",
                                evidence={"share": share})
        return None

    def scan(self, ctx: Context, joint: bool = False) -> tuple[float, np.ndarray, list]:
        """(delay d, its regressor, its signature) of the trial delay whose signature
        explains most on the estimation part; ``joint``: the linearised refit's signature."""
        lin = ctx.through_model(ctx.u)
        best = (-1.0, 0.0, None, None)
        for d in self._grid(ctx):
            z = ctx.through_model(_shifted(ctx.u, d)) - lin
            sig = joint_signature(ctx, [z]) if joint else signature_fit(ctx, [z])
            if sig.score_est > best[0]:
                best = (sig.score_est, d, z, sig)
        return best[1], best[2], best[3]

    def _scan(self, ctx: Context) -> tuple[float, np.ndarray, list]:
        """The plain scan, or on a generic record whose plain scan is not decisive the
        linearised one when that is (module docstring)."""
        plain = self.scan(ctx)
        if ctx.submodel != "generic" or (plain[2].f_p < P_LEVEL
                                          and plain[2].score >= self.min_score):
            return plain
        joint = self.scan(ctx, joint=True)
        if joint[2].f_p < P_LEVEL and joint[2].score >= self.min_score:
            joint[2].extra["linearised"] = True
            return joint
        return plain

    def _signature(self, ctx):
        d, z, sig = self._scan(ctx)
        sig.extra["delay_samples"] = float(d)
        return sig

    def regressors(self, ctx):
        d = self.signature(ctx).extra["delay_samples"]
        return [ctx.through_model(_shifted(ctx.u, d)) - ctx.through_model(ctx.u)]

    def evidence(self, ctx, sig):
        """Evidence code (``lag`` / ``lead``) and numbers (rigd.diagnose.wording)."""
        d = sig.extra.get("delay_samples", 0.0) * float(sig.beta[0] if sig.beta.size else 1.0)
        ev = {"delay_samples": float(d), "delay_ms": float(1000 * d / ctx.fs)}
        return ("lag" if d > 0 else "lead"), ev  # a lead is never printed as a negative delay

    def refitted_evidence(self, ctx, theta_e) -> dict:
        """The refit's delay (the size reported once refitted: the signature's first-order
        estimate d·β overshoots when the base had absorbed part of the lag)."""
        d = max(float(theta_e[0]), 0.0)
        out = {"delay_samples": d, "delay_ms": 1000 * d / ctx.fs}
        return dict(out, code="lag") if d > 0 else out

    def implausible(self, ctx, theta_e):
        d = float(theta_e[0])
        if d >= MIN_DELAY_SAMPLES:
            return None
        return (f"a lag of {max(d, 0.0):.2f} samples ({N.duration(max(d, 0.0) / ctx.fs)}) "
                "improves the fit, but a "
                f"delay shorter than {MIN_DELAY_SAMPLES:g} sample cannot be told from "
                f"unmodelled fast dynamics at {ctx.fs:g} Hz: the model misses some "
                "high-frequency phase lag (e.g. valve or sensor dynamics of higher order than "
                "the model), not a transport delay")

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        return ["delay_samples"]

    def param_bounds(self, base):
        return np.array([0.0]), np.array([200.0])

    def warm_start(self, ctx, sig):
        d = sig.extra.get("delay_samples", 0.0) * float(sig.beta[0] if sig.beta.size else 1.0)
        return np.array([max(0.0, d)])

    def linear(self, G, theta_e, base, fs):
        """e^{−s d/fs} on every input, a Padé approximant (rigd.effects._linear)."""
        d = max(0.0, float(theta_e[0]))
        block = delay_block(d / fs, pade_order(d))
        return series_inputs(G, [block] * G.ninputs)

    def input_block(self, u, theta_e, data):
        """Every input delayed by d = θe[0] ≥ 0 samples (fractional: interpolated)."""
        return _shifted(u, max(0.0, float(theta_e[0])))


def _shifted(u: np.ndarray, d: float) -> np.ndarray:
    """Each column of (n, nu) ``u`` delayed by ``d`` samples (fractional: interpolated)."""
    return np.column_stack([shift(u[:, j], d) for j in range(u.shape[1])])
