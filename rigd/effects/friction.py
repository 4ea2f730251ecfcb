"""``friction``: Coulomb and viscous friction in a positioning mechanism (requires a mechanical
base).

The mass-normalised mechanical model p̈ + D ṗ + K p = B u gains, per axis, a force of constant
size against the motion, −F_c,i sgn(ṗ_i), with sgn smoothed as tanh(ṗ_i / v_ε,i) over a
smoothing velocity v_ε (a share of the record's rms velocity: the same for any unit or rate);
the viscous part is the base's own damping D (reported beside F_c). It is a feedback block of
the state (Lur'e form φ(C_f x) into B_f, C_f the velocities), integrated by the mechanical
simulator (``MechanicalFeedback.friction``, RK4 with sub-steps where the smoothed sign is
steep).

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

from rigd.effects.base import Effect, dims, is_mechanical
from rigd.effects.context import CannotReveal, Context
from rigd.effects.linearised import joint_signature
from rigd.effects.signature import SignatureFit
from rigd.ident.feedback import MechanicalFeedback

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
    site = "state"
    sites = ("state",)
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
        # worded by rigd.diagnose.advice for the record's domain
        return CannotReveal(self.name, "", "", ctx.submodel, code="no_reversal",
                            evidence={"min_each_way": MIN_EACH_WAY})

    def regressors(self, ctx):
        ve = self._veps(ctx)
        return [ctx.through_force(smooth_sign(ctx.yhat[:, i], ctx.fs, ve[i]), i)
                for i in range(ctx.ny)]

    def _signature(self, ctx: Context) -> SignatureFit:
        """The linearised refit (module docstring): share and F test of the friction forces
        beyond the base model's sensitivities; ``beta`` their coefficients."""
        return joint_signature(ctx, self.regressors(ctx))

    def evidence(self, ctx, sig):
        """Evidence code and numbers (worded by rigd.diagnose.wording): the Coulomb force
        per axis (acceleration units, and through the base's input gain in input units),
        the smoothing velocity and the base's viscous damping."""
        fc = -np.asarray(sig.beta, float)
        ev = {"coulomb_accel": fc.tolist(), "smoothing_velocity": self._veps(ctx).tolist()}
        if is_mechanical(ctx.structure):   # states [p, ṗ]
            A, B, _, _, _ = ctx.structure.continuous(ctx.theta)
            A, B = np.asarray(A, float), np.asarray(B, float)
            m = B.shape[0] // 2
            ev["viscous_per_s"] = (-np.diag(A[m:, m:])).tolist()   # the base's damping D_ii
            j = [int(np.argmax(np.abs(B[m + i]))) for i in range(ctx.ny)]
            ev["coulomb_input_units"] = [float(fc[i] / B[m + i, j[i]]) if B[m + i, j[i]]
                                         else None for i in range(ctx.ny)]
        i = int(np.argmax(np.abs(fc))) if fc.size else 0
        ev["output"] = ctx.label(i)
        ev["against_motion"] = bool(fc.size and fc[i] > 0)
        return "friction.coulomb", ev

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

    def state_block(self, theta_e, data):
        """F_c tanh(ṗ / v_ε) against the motion, per axis."""
        th = np.asarray(theta_e, float)
        m = th.size // 2
        return MechanicalFeedback(friction=np.vstack([th[:m], th[m:]]))
