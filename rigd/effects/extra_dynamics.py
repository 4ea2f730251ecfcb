"""``extra_dynamics``: an unmodelled real pole or lag (thermal lag, a sensor's or actuator's
first-order dynamics) on any base; ``extra_mode`` stays the name for an unmodelled *mode*.

Extension: a parallel first-order path from every input to every output,

    y_i = ŷ_i + Σ_j g_ij · 1/(τ s + 1) u_j,

one real pole at −1/τ with its gains (the model gains a real mode). τ is bounded relative to
the record (half a sample to a quarter of the estimation part), ``g`` is dimensionless per
unit (output per input unit).

Signature: the residual regressed on the first-order lags of the inputs, τ scanned over a
geometric grid in samples (relative to the rate); the best τ (estimation part) is kept and
starts the refit. Low-pass, coherent with the input, no narrow peak.
"""

from __future__ import annotations

import numpy as np

from rigd.effects._linear import parallel
from rigd.effects._signals import lag1
from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.signature import SignatureFit, signature_fit

#: τ grid and bounds, samples: from half a sample to a quarter of the estimation part
TAU_MIN_SAMPLES = 0.5
TAU_MAX_SHARE = 0.25
GRID = 16
#: a fitted τ below this (samples) is a feedthrough, not a lag
MIN_TAU_SAMPLES = 1.0
#: nominal size for "cannot tell": a lag path adding this share of the output's spread
NOMINAL_SHARE = 0.1


class ExtraDynamics(Effect):
    name = "extra_dynamics"
    site = "output"
    sites = ("output",)
    #: its output block is y + g(u, θ): the base's output sensitivities hold through it
    additive_output = True
    submodels = ("generic",)
    physics = "an unmodelled real pole or lag (thermal, sensor or actuator lag)"

    def _taus(self, ctx: Context) -> np.ndarray:
        n_est = len(range(*ctx.est.indices(ctx.n)))
        hi = max(TAU_MAX_SHARE * n_est, 2.0)
        return np.geomspace(1.0, hi, GRID) / ctx.fs

    def _regs(self, ctx: Context, tau: float) -> list[np.ndarray]:
        u = ctx.u - ctx.u[ctx.est].mean(axis=0)
        out = []
        for j in range(ctx.nu):
            lj = lag1(u[:, j], tau, ctx.fs)
            for i in range(ctx.ny):
                g = np.zeros((ctx.n, ctx.ny))
                g[:, i] = lj
                out.append(g)
        return out

    def _signature(self, ctx: Context) -> SignatureFit:
        best = None
        for tau in self._taus(ctx):
            s = signature_fit(ctx, self._regs(ctx, tau))
            s.extra["tau_s"] = float(tau)
            if best is None or s.score_est > best.score_est:
                best = s
        return best

    def regressors(self, ctx):
        return self._regs(ctx, self.signature(ctx).extra["tau_s"])

    def reveal(self, ctx: Context) -> CannotReveal | None:
        def nominal():
            noms = []
            for tau in self._taus(ctx)[::3]:
                regs = self._regs(ctx, tau)
                size = [NOMINAL_SHARE * np.std(ctx.y[ctx.est, k % ctx.ny])
                        / max(np.std(g[ctx.est, k % ctx.ny]), 1e-300)
                        for k, g in enumerate(regs)]
                noms.append(sum(c * g for c, g in zip(size, regs)))
            return noms

        return self.reveal_at_nominal(ctx, nominal, 1 + ctx.nu * ctx.ny, "too_small",
                                      {"nominal_share": NOMINAL_SHARE})

    def evidence(self, ctx, sig):
        """Evidence code and numbers (worded by rigd.diagnose.wording)."""
        tau = float(sig.extra.get("tau_s", 0.0))
        g = np.asarray(sig.beta, float).reshape(ctx.nu, ctx.ny)
        return "extra_dynamics.real_pole", {"time_constant_s": tau,
                                            "time_constant_samples": tau * ctx.fs,
                                            "gain": g.tolist()}

    def implausible(self, ctx, theta_e):
        tau = float(theta_e[0])
        if tau * ctx.fs >= MIN_TAU_SAMPLES:
            return None
        return (f"a parallel lag of {tau * ctx.fs:.2f} samples improves the fit: a direct "
                "feedthrough (or fast dynamics) the model lacks, not a lag that the record "
                "resolves")

    # --- extension ----------------------------------------------------------------------
    def param_names(self, base):
        ny, nu = dims(base)
        return ["ed_tau"] + [f"ed_g{j}_{i}" for j in range(nu) for i in range(ny)]

    def param_bounds(self, base):
        k = len(self.param_names(base))
        lo, hi = np.full(k, -np.inf), np.full(k, np.inf)
        lo[0] = 0.0
        return lo, hi

    def record_bounds(self, base, rec):
        lo, hi = self.param_bounds(base)
        lo[0] = TAU_MIN_SAMPLES / rec.fs
        hi[0] = max(TAU_MAX_SHARE * rec.n, 2.0) / rec.fs
        return lo, hi

    def param_typical(self, base, rec):
        ny, nu = dims(base)
        su = np.resize(np.asarray(rec.u_spread, float), nu)
        sy = np.resize(np.asarray(rec.y_spread, float), ny)
        return np.concatenate([[10.0 / rec.fs], np.outer(1.0 / su, sy).ravel()])

    def theta0_effect(self, base, data):
        ny, nu = dims(base)
        return np.concatenate([[10.0 / float(data.fs)], np.zeros(nu * ny)])

    def warm_start(self, ctx, sig):
        return np.concatenate([[sig.extra["tau_s"]], np.asarray(sig.beta, float)])

    def linear(self, G, theta_e, base, fs):
        """The parallel lag: y += Σ_j g_j u_j/(τ s + 1)."""
        nu, ny = G.ninputs, G.noutputs
        th = np.asarray(theta_e, float)
        tau, g = max(th[0], 1e-12), th[1:].reshape(nu, ny)
        return parallel(G, -np.eye(nu) / tau, np.eye(nu) / tau, g.T)

    def output_block(self, y, theta_e, data):
        """y + Σ_j g_j · lag(u_j, τ): the parallel first-order path."""
        u = np.asarray(data.inputs, float)
        ny, nu = y.shape[1], u.shape[1]
        th = np.asarray(theta_e, float)
        g = th[1:].reshape(nu, ny)
        if not np.any(g):
            return y
        lags = np.column_stack([lag1(u[:, j], th[0], float(data.fs)) for j in range(nu)])
        return y + lags @ g
