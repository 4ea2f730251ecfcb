"""``integrator``: a pole at zero the base lacks (position from velocity, level from flow).

Often seen only under feedback: a controller keeps the integrating plant's output bounded, so
the record looks stationary while the base model (a spring where there is none, a static gain
that grows without bound as the frequency falls) misses the drift that integrates the input.

Extension: a parallel integrating path from every input to every output,

    y_i = ŷ_i + Σ_j g_ij ∫ (u_j − b_j) dt,

with the input bias b_j the integrator sees (a controller's output under feedback settles
where the plant's integrator stops moving, so the integrator's zero is not the record's).
``g`` in output units per input unit per second, ``b`` in input units; their step sizes and
bounds are relative to the record (:class:`rigd.effects.scales.RecordScale`).

Signature: the residual regressed on ∫u_j on each output and a ramp on each output (the bias).
A base that already integrates (its slowest real pole slower than the estimation part is
long: the mechanical base with a spring at the frequency floor) carries the integrator: it is
named from the base (:meth:`Integrator.carried_by_base`, evidence ``in_base``), not added.
The evidence says whether the input reacts to what the model cannot explain
(``feedback_test``, Ljung's residual–future-input correlation: closed-loop data) and carries
the advice code ``identify_closed_loop`` (identify in closed loop or with the controller;
the words are rigd.diagnose's).
"""

from __future__ import annotations

import numpy as np

from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context, Finding
from rigd.ident.figures import fit_percent

#: nominal size for "cannot tell": an integrating path adding this share of the output spread
NOMINAL_SHARE = 0.1


def integral(u: np.ndarray, fs: float) -> np.ndarray:
    """Running integral (trapezoid) of ``u`` (n, k) along axis 0, starting at 0, units·s."""
    u = np.asarray(u, float)
    out = np.zeros_like(u)
    out[1:] = np.cumsum(0.5 * (u[1:] + u[:-1]), axis=0) / fs
    return out


def feedback_evidence(u: np.ndarray, r: np.ndarray, lags: int = 10) -> float:
    """Largest |correlation| of the residual ``r`` (n, ny) with the *present and future*
    inputs ``u`` (n, nu), u[t + k], k = 0..lags, in units of its 99 % bound (2.58/√n): above
    1, the input reacts to what the model cannot explain — a controller closes the loop
    (Ljung's test for feedback; in open loop the input is independent of the disturbance)."""
    u = np.asarray(u, float) - np.mean(u, axis=0)
    r = np.asarray(r, float) - np.mean(r, axis=0)
    n = u.shape[0]
    su, sr = np.linalg.norm(u, axis=0), np.linalg.norm(r, axis=0)
    if n < 2 * lags or not (np.all(su > 0) and np.all(sr > 0)):
        return 0.0
    best = 0.0
    for k in range(lags + 1):
        c = (r[:n - k].T @ u[k:]) / np.outer(sr, su)
        best = max(best, float(np.max(np.abs(c))))
    return best / (2.58 / np.sqrt(n))


def slowest_real_pole(structure, theta) -> float | None:
    """Time constant (s) of the base model's slowest real pole, from its continuous state
    matrix (None without one; inf for a pole at zero)."""
    try:
        lam = np.linalg.eigvals(np.asarray(structure.continuous(theta)[0], float))
    except NotImplementedError:
        return None
    except (np.linalg.LinAlgError, ValueError):
        return None
    real = [abs(lm.real) for lm in lam if abs(lm.imag) <= 1e-9 * max(abs(lm), 1e-300)]
    if not real:
        return None
    slow = min(real)
    return float("inf") if slow == 0 else 1.0 / slow


class Integrator(Effect):
    name = "integrator"
    site = "output"
    sites = ("output",)
    #: its output block is y + g(u, θ): the base's output sensitivities hold through it
    additive_output = True
    submodels = ("generic",)
    physics = "a pole at zero (an integrating plant) the model lacks"
    linear_note = ("an integrating path (a pole at zero) is left out of the design model")

    def _regs(self, ctx: Context) -> list[np.ndarray]:
        iu = integral(ctx.u - ctx.u[ctx.est].mean(axis=0), ctx.fs)
        t = (np.arange(ctx.n) - ctx.n / 2) / ctx.fs
        out = []
        for j in range(ctx.nu):
            for i in range(ctx.ny):
                g = np.zeros((ctx.n, ctx.ny))
                g[:, i] = iu[:, j]
                out.append(g)
        for i in range(ctx.ny):
            g = np.zeros((ctx.n, ctx.ny))
            g[:, i] = t
            out.append(g)
        return out

    def regressors(self, ctx):
        return self._regs(ctx)

    def reveal(self, ctx: Context) -> CannotReveal | None:
        def nominal():
            iu = integral(ctx.u - ctx.u[ctx.est].mean(axis=0), ctx.fs)
            noms = []
            for j in range(ctx.nu):
                s = np.std(iu[ctx.est, j]) or 1.0
                for i in range(ctx.ny):
                    g = np.zeros((ctx.n, ctx.ny))
                    g[:, i] = NOMINAL_SHARE * np.std(ctx.y[ctx.est, i]) * iu[:, j] / s
                    noms.append(g)
            return noms

        return self.reveal_at_nominal(ctx, nominal, ctx.nu * ctx.ny + ctx.ny, "too_small",
                                      {"nominal_share": NOMINAL_SHARE})

    def carried_by_base(self, ctx: Context) -> Finding | None:
        """A finding when the base model already integrates: its slowest real pole is slower
        than the estimation part is long (on this record it cannot be told from a pole at
        zero). Then the integrator is named from the base, not added."""
        tau = slowest_real_pole(ctx.structure, ctx.theta)
        t_est = len(range(*ctx.est.indices(ctx.n))) / ctx.fs
        if tau is None or not tau > t_est:
            return None
        fp = float(np.mean(fit_percent(ctx.y[ctx.val], ctx.yhat[ctx.val])))
        ev = self._evidence(ctx, in_base=True)
        ev["time_constant_s"] = tau
        ev["estimation_seconds"] = t_est
        # the words are the diagnosis' (rigd.diagnose.wording, from the code)
        return Finding(self.name, 0.0, True, "", ctx.submodel, 0.0, fp, ev)

    def _evidence(self, ctx: Context, in_base: bool) -> dict:
        fb = feedback_evidence(ctx.u[ctx.val], ctx.residual[ctx.val])
        return {"code": "integrator.in_base" if in_base else "integrator.added",
                "in_base": in_base, "feedback_test": fb, "feedback_suspected": bool(fb > 1.0),
                # an integrating plant is identified in closed loop or with its controller
                "advice": "identify_closed_loop"}

    def evidence(self, ctx, sig):
        """Evidence code and numbers (worded by rigd.diagnose.wording)."""
        k = ctx.nu * ctx.ny
        g = np.asarray(sig.beta, float)[:k].reshape(ctx.nu, ctx.ny)
        j, i = np.unravel_index(int(np.argmax(np.abs(g))), g.shape) if k else (0, 0)
        ev = self._evidence(ctx, in_base=False)
        code = ev.pop("code")
        return code, dict(ev, gain_per_s=g.tolist(), input=ctx.label(int(j), "in"),
                          output=ctx.label(int(i)))

    # --- extension ----------------------------------------------------------------------
    def param_names(self, base):
        ny, nu = dims(base)
        return ([f"int_g{j}_{i}" for j in range(nu) for i in range(ny)]
                + [f"int_b{j}" for j in range(nu)])

    def param_typical(self, base, rec):
        ny, nu = dims(base)
        su = np.resize(np.asarray(rec.u_spread, float), nu)
        sy = np.resize(np.asarray(rec.y_spread, float), ny)
        dur = rec.n / rec.fs
        g = np.outer(1.0 / su, sy).ravel() / dur   # the spread over the record per spread
        return np.concatenate([g, su])

    def warm_start(self, ctx, sig):
        k = ctx.nu * ctx.ny
        beta = np.asarray(sig.beta, float)
        g = beta[:k].reshape(ctx.nu, ctx.ny)
        r = beta[k:]
        # the ramp r_i = −Σ_j g_ij (b_j − ū_j), ū the estimation mean used by the regressors
        ubar = ctx.u[ctx.est].mean(axis=0)
        b = ubar - np.linalg.lstsq(g.T, r, rcond=None)[0] if np.any(g) else ubar
        return np.concatenate([g.ravel(), b])

    def theta0_effect(self, base, data):
        ny, nu = dims(base)
        return np.concatenate([np.zeros(nu * ny), np.mean(np.asarray(data.inputs, float),
                                                          axis=0)])

    def output_block(self, y, theta_e, data):
        """y + ∫(u − b) dt · g: the integrating path."""
        ny, nu = y.shape[1], np.asarray(data.inputs).shape[1]
        th = np.asarray(theta_e, float)
        g = th[:nu * ny].reshape(nu, ny)
        if not np.any(g):
            return y
        b = th[nu * ny:]
        return y + integral(np.asarray(data.inputs, float) - b, float(data.fs)) @ g
