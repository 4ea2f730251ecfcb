"""``cross_coupling``: gyroscopic / cross-coupled film forces missing from a decoupled model.

Eq. 4 has the gyroscopic term −Ω G ṗ with G antisymmetric, and a fluid film couples x and y
(cross stiffness k_xy). A decoupled (diagonal) model leaves the residual of one axis
correlated with the motion (and so the input) of the other. Signature: the residual is
explained by the model response to the *other* axis' position and velocity acting as a force
on each axis. Extension: off-diagonal increments dK, dD of the (mass-normalised) stiffness and
damping matrices, p̈ + (D + dD) ṗ + (K + dK) p = B u (cross stiffness, gyroscopic −Ω G).

Posed on rotor records: the base is the bearing model with diagonal K, D, B (decoupled axes);
at Ω > 0 the gyroscopic coupling is what it misses.
"""

from __future__ import annotations

import numpy as np

from rigd.effects._linear import mechanical_shift
from rigd.effects._signals import derivative
from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.ident.feedback import MechanicalFeedback


def _offdiag(n: int) -> list[tuple[int, int]]:
    return [(j, i) for j in range(n) for i in range(n) if i != j]


class CrossCoupling(Effect):
    name = "cross_coupling"
    sites = ("state",)
    requires = ("mechanical",)
    submodels = ("bearing", "generic")
    physics = "cross-coupled (gyroscopic) forces between the axes"

    def reveal(self, ctx: Context) -> CannotReveal | None:
        ev = {"nu": ctx.nu, "ny": ctx.ny}
        if ctx.ny < 2 or ctx.nu != ctx.ny:  # worded by rigd.diagnose.advice
            return CannotReveal(self.name, "", "", ctx.submodel, code="paths", evidence=ev)
        c = np.corrcoef(ctx.u.T)
        if np.max(np.abs(c[np.triu_indices(ctx.nu, 1)])) > 0.95:
            return CannotReveal(self.name, "", "", ctx.submodel, code="same_signal",
                                evidence=ev)
        return None

    def regressors(self, ctx):
        yh = ctx.yhat - ctx.yhat[ctx.est].mean(axis=0)
        dy = derivative(yh, ctx.fs)
        pairs = _offdiag(ctx.ny)
        return ([ctx.through_force(yh[:, i], j) for j, i in pairs]
                + [ctx.through_force(dy[:, i], j) for j, i in pairs])

    def evidence(self, ctx, sig):
        """Evidence code ``coupling`` and numbers (rigd.diagnose.wording)."""
        pairs = _offdiag(ctx.ny)
        npair = len(pairs)
        regs_share = []
        r = ctx.residual[ctx.val]
        u = ctx.u[ctx.val]
        for j, i in pairs:  # residual of axis j vs input of axis i
            cc = np.corrcoef(r[:, j], u[:, i])[0, 1] if np.std(u[:, i]) > 0 else 0.0
            regs_share.append(float(cc))
        k = int(np.argmax(np.abs(regs_share)))
        j, i = pairs[k]
        b = np.asarray(sig.beta, float)
        b = -b  # regression coefficients are −dK, −dD
        gyro = np.all(np.sign(b[npair:]) != 0) and npair == 2 and b[npair] * b[npair + 1] < 0
        return "coupling", {
            "cross_stiffness": b[:npair].tolist(), "cross_damping": b[npair:].tolist(),
            "residual_input_corr": {f"{ctx.label(jj)}~{ctx.label(ii, 'in')}": v
                                    for (jj, ii), v in zip(pairs, regs_share)},
            "output": ctx.label(j), "input": ctx.label(i, "in"), "corr": regs_share[k],
            "antisymmetric": bool(gyro), "omega_hz": float(ctx.omega_hz)}

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        ny, nu = dims(base)
        pairs = _offdiag(min(ny, nu))
        return [f"kc_{j}_{i}" for j, i in pairs] + [f"dc_{j}_{i}" for j, i in pairs]

    def warm_start(self, ctx, sig):
        return -np.asarray(sig.beta, float)

    def _F(self, theta_e, n):
        pairs = _offdiag(n)
        Kc, Dc = np.zeros((n, n)), np.zeros((n, n))
        for v, (j, i) in zip(theta_e[:len(pairs)], pairs):
            Kc[j, i] = v
        for v, (j, i) in zip(theta_e[len(pairs):], pairs):
            Dc[j, i] = v
        return Kc, Dc

    #: why :meth:`linear` may have no block (a base not in mechanical form)
    linear_note = "the base is not a mechanical model in states [p, ṗ]"

    def linear(self, G, theta_e, base, fs):
        """K + K_c, D + D_c in the mechanical base (states [p, ṗ])."""
        n = G.noutputs
        Kc, Dc = self._F(np.asarray(theta_e, float), n)
        return mechanical_shift(G, Kc, Dc)

    def state_block(self, theta_e, data):
        """K_c p + D_c ṗ: a linear feedback folded into K and D."""
        Kc, Dc = self._F(np.asarray(theta_e, float), np.asarray(data.outputs).shape[1])
        return MechanicalFeedback(dK=Kc, dD=Dc)
