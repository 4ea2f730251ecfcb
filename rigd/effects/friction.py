"""``friction``: Coulomb and viscous friction in a positioning mechanism (requires a mechanical
base).

The mass-normalised mechanical model p̈ + D ṗ + K p = B u gains, per axis, a force of constant
size against the motion, −F_c,i sgn(ṗ_i), with sgn smoothed as tanh(ṗ_i / v_ε,i) over a
smoothing velocity v_ε (a share of the record's rms velocity: the same for any unit or rate);
the viscous part is the base's own damping D (reported beside F_c). It is a feedback block of
the state (Lur'e form φ(C_f x) into B_f, C_f the velocities), integrated by the mechanical
simulator (``Hooks.friction``, RK4 with sub-steps where the smoothed sign is steep).

Signature: a *linearised refit* (promoted from the dry-friction probe that described it under
*unexplained* before it was in the catalogue): the base residual regressed on the model's
response to tanh(ṗ̂_i / v_ε) fed as a force on axis i *together with* the model's own
sensitivities ∂ŷ/∂θ (rigd.effects.detectability.parameter_responses) and a constant per
output, on the estimation part; the share is what the force adds to the sensitivities alone,
with an F test on an autocorrelation-corrected sample size. The sensitivities matter: a linear
fit absorbs a strong friction into a spring and too much damping, after which the residual
alone barely correlates with the friction's response while the joint step explains most of
it. The share is in-sample (a strong force moves the linear parameters further than a
first-order step extrapolates); the refit then decides out of sample.
"""

from __future__ import annotations

import numpy as np

from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.detectability import parameter_responses
from rigd.effects.signature import SignatureFit, effective_n

#: sgn(v) is smoothed as tanh(v / v_ε), v_ε this share of the rms velocity of the record
SMOOTH = 0.05
#: a motion must reverse: each direction at least this share of the samples
MIN_EACH_WAY = 0.1


def rms_velocity(y: np.ndarray, fs: float) -> np.ndarray:
    """Per-column rms of the time derivative of ``y`` (n, ny), output units / s (≥ tiny)."""
    v = np.gradient(np.asarray(y, float), axis=0) * fs
    return np.maximum(np.sqrt(np.mean(v * v, axis=0)), 1e-300)


def smooth_sign(p: np.ndarray, fs: float, v_eps: float) -> np.ndarray:
    """tanh(ṗ / v_ε) of the (n,) position ``p``."""
    return np.tanh(np.gradient(np.asarray(p, float)) * fs / v_eps)


class Friction(Effect):
    name = "friction"
    level = "state"
    site = "state"
    requires = ("mechanical",)
    submodels = ("generic",)
    physics = "Coulomb and viscous friction in a positioning mechanism"

    def _veps(self, ctx: Context) -> np.ndarray:
        return SMOOTH * rms_velocity(ctx.yhat[ctx.est], ctx.fs)

    def reveal(self, ctx: Context) -> CannotReveal | None:
        ve = self._veps(ctx)
        for i in range(ctx.ny):
            s = smooth_sign(ctx.yhat[:, i], ctx.fs, ve[i])
            if min(np.mean(s > 0.5), np.mean(s < -0.5)) >= MIN_EACH_WAY:
                return None
        return CannotReveal(self.name, "the motion never reverses (each direction under "
                            f"{100 * MIN_EACH_WAY:.0f} % of the record): a force of constant "
                            "size against the motion cannot be told from an offset",
                            "re-run with an input that moves back and forth (a slow triangle "
                            "or a low-frequency multisine)", ctx.submodel)

    def regressors(self, ctx):
        ve = self._veps(ctx)
        return [ctx.through_force(smooth_sign(ctx.yhat[:, i], ctx.fs, ve[i]), i)
                for i in range(ctx.ny)]

    def signature(self, ctx: Context) -> SignatureFit:
        """The linearised refit (module docstring): share and F test of the friction forces
        beyond the base model's sensitivities; ``beta`` their coefficients."""
        key = ("signature", self.name)
        if key in ctx.cache:
            return ctx.cache[key]
        regs = self.regressors(ctx)
        J = sensitivities(ctx)
        if J is None or not regs:
            sig = SignatureFit(0.0, np.zeros(len(regs)), 1.0, len(regs))
        else:
            share, p, beta = joint_share(ctx, np.stack(regs, axis=-1), J)
            sig = SignatureFit(share, beta[:len(regs)], p, len(regs), share)
        ctx.cache[key] = sig
        return sig

    def explain(self, ctx, sig):
        fc = -np.asarray(sig.beta, float)
        ev = {"code": "friction.coulomb", "coulomb_accel": fc.tolist(),
              "smoothing_velocity": self._veps(ctx).tolist()}
        cont = getattr(ctx.structure, "continuous", None)
        if callable(cont):
            _, B, _, _, _ = cont(ctx.theta)
            B = np.asarray(B, float)
            m = B.shape[0] // 2
            A = np.asarray(cont(ctx.theta)[0], float)
            ev["viscous_per_s"] = (-np.diag(A[m:, m:])).tolist()   # the base's damping D_ii
            j = [int(np.argmax(np.abs(B[m + i]))) for i in range(ctx.ny)]
            ev["coulomb_input_units"] = [float(fc[i] / B[m + i, j[i]]) if B[m + i, j[i]]
                                         else None for i in range(ctx.ny)]
        i = int(np.argmax(np.abs(fc))) if fc.size else 0
        return (f"the error jumps with the sign of the velocity of {ctx.label(i)}: a force of "
                f"constant size {'against' if fc.size and fc[i] > 0 else 'along'} the motion "
                f"(dry friction; the viscous part is the model's damping); explains "
                f"{100 * sig.score:.0f} % of the residual", ev)

    # --- extension ----------------------------------------------------------------------
    def param_names(self, base):
        ny, _ = dims(base)
        return [f"fr_c_{i + 1}" for i in range(ny)] + [f"fr_v_{i + 1}" for i in range(ny)]

    def theta0_effect(self, base, data):
        ve = SMOOTH * rms_velocity(np.asarray(data.outputs, float), float(data.fs))
        return np.concatenate([np.zeros(ve.size), ve])

    def param_bounds(self, base):
        ny, _ = dims(base)
        return (np.concatenate([np.zeros(ny), np.full(ny, 1e-300)]),
                np.full(2 * ny, np.inf))

    def record_bounds(self, base, rec):
        ny, _ = dims(base)
        # v_ε between 1e-6 and 1 of the output's spread per sample
        vs = np.resize(np.asarray(rec.y_spread, float), ny) * rec.fs
        return (np.concatenate([np.zeros(ny), 1e-6 * vs]),
                np.concatenate([np.full(ny, np.inf), vs]))

    def param_typical(self, base, rec):
        ny, _ = dims(base)
        ys = np.resize(np.asarray(rec.y_spread, float), ny)
        # a force that moves the output by its spread within ~n/100 samples: spread · (fs/10)²
        return np.concatenate([ys * (rec.fs / 10) ** 2, 1e-2 * ys * rec.fs])

    def warm_start(self, ctx, sig):
        fc = np.maximum(-np.asarray(sig.beta, float), 0.0)
        return np.concatenate([fc, self._veps(ctx)])

    def refit_fixed(self, ext, sig=None) -> list[str]:
        """The smoothing velocities stay at their start (a resolution, not physics)."""
        return [n for n in ext.names if n.startswith("fr_v_")]

    def apply_hooks(self, theta_e, hooks, data):
        th = np.asarray(theta_e, float)
        m = th.size // 2
        fr = np.vstack([th[:m], th[m:]])
        if hooks.friction is not None:  # never twice in one model (resolve refuses it)
            raise ValueError("friction added twice")
        hooks.friction = fr

    def feedback(self, p, theta_e, fs, nu):
        th = np.asarray(theta_e, float)
        m = th.size // 2
        s = np.column_stack([smooth_sign(p[:, i], fs, th[m + i]) for i in range(p.shape[1])])
        return (-s * th[None, :m])[:, :nu]


def sensitivities(ctx: Context) -> np.ndarray | None:
    """∂ŷ/∂θ of the base model over the whole record, (n, ny, q), from the stepped
    simulations of :func:`rigd.effects.detectability.parameter_responses` (the parameters
    that move the output) and one constant column per output; None if one failed."""
    y0 = np.asarray(ctx.yhat, float)
    cols = []
    for _, h, yi in parameter_responses(ctx):
        if yi is None:
            return None
        d = (yi - y0) / h
        if np.all(np.isfinite(d)) and np.any(d):
            cols.append(d)
    for i in range(ctx.ny):
        c = np.zeros_like(y0)
        c[:, i] = 1.0
        cols.append(c)
    return np.stack(cols, axis=-1)


def joint_share(ctx: Context, G: np.ndarray, J: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(share, F-test p, coefficients): the share of the base residual's energy (estimation
    part, outputs weighted 1/std as the fit) that the regressors ``G`` (n, ny, k) add to the
    sensitivities ``J`` (n, ny, q), and the joint least-squares coefficients [G, J]."""
    from scipy import stats

    w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
    re = (ctx.residual[ctx.est] * w).reshape(-1)
    X = np.concatenate([G, J], axis=-1)[ctx.est] * w[None, :, None]
    k, q = G.shape[-1], X.shape[-1]
    Xe = X.reshape(-1, q)
    if not np.all(np.isfinite(Xe)):
        return 0.0, 1.0, np.zeros(q)
    nrm = np.linalg.norm(Xe, axis=0)
    nrm[nrm == 0] = 1.0
    fits = []
    for cols in (slice(0, q), slice(k, q)):        # with the forces, and without
        b = np.linalg.lstsq(Xe[:, cols] / nrm[cols], re, rcond=None)[0] / nrm[cols]
        e = re - Xe[:, cols] @ b
        fits.append((float(e @ e), b))
    (sse1, beta), (sse0, _) = fits
    share = max(0.0, (sse0 - sse1) / (float(re @ re) or 1e-300))
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - q, 1.0)
    F = ((sse0 - max(sse1, 1e-300)) / k) / (max(sse1, 1e-300) / dof)
    return share, float(stats.f.sf(max(F, 0.0), k, dof)), beta
