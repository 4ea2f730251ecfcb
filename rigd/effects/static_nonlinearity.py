"""``static_nonlinearity``: a static curve at the input (Hammerstein) or the output (Wiener).

A valve or sensor characteristic, a titration curve, a saturation-like gain: the linear model
is right but a static function bends the signal before it (input site) or after it (output
site). Posed as a polynomial of degree 3 on each input and each output,

    u'_j = u_j + a2_j u_j² + a3_j u_j³,     y_i = ŷ_i + c2_i ŷ_i² + c3_i ŷ_i³,

the block form of a Hammerstein–Wiener model (input blocks → base → output blocks).

Signature: the linearised refit (:mod:`rigd.effects.linearised`) of the base model's response
to the input's square and cube (input site) and of the square and cube of the model output
(output site), each together with the base model's own sensitivities (a linear fit absorbs a
strong curve into a wrong gain and time constants; the residual alone then barely shows it);
the site whose regressors add more (estimation part) is the one named (``site`` in the
finding) and refitted, the other site's coefficients stay at 0. ``rigd identify --add
static_nonlinearity`` fits both sites. Parameters are in the signals' units; their step sizes
and bounds are relative to the record's spreads (:class:`rigd.effects.scales.RecordScale`).
"""

from __future__ import annotations

import numpy as np

from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.linearised import joint_signature
from rigd.effects.signature import SignatureFit

#: largest |coefficient| × spread^(k−1): the curve may bend the signal by a few times its
#: own size over its range, not more
MAX_BEND = 5.0
#: nominal size for "cannot tell": a curve bending the signal by this share at its spread
NOMINAL_BEND = 0.1
SITES = ("input", "output")


def _centred_powers(x: np.ndarray, est: slice) -> tuple[np.ndarray, np.ndarray]:
    """(x² − mean, x³) of (n,) ``x`` centred on its estimation-part mean."""
    xc = x - np.mean(x[est])
    sq = xc ** 2
    return sq - np.mean(sq[est]), xc ** 3


class StaticNonlinearity(Effect):
    name = "static_nonlinearity"
    site = "input/output"
    sites = ("input", "output")
    submodels = ("generic",)
    physics = "a static curve at the input or output (valve or sensor characteristic)"
    #: not screened by default yet: on the cascaded tanks it is named at the input (the
    #: square-root outflows' level-dependent gain) and on a Duffing record it competed with
    #: cubic_stiffness; asked for with --effects / --add
    screened = False

    # --- signature --------------------------------------------------------------------
    def _regs(self, ctx: Context, site: str) -> list[np.ndarray]:
        if site == "input":
            out = []
            for j in range(ctx.nu):
                for p in _centred_powers(ctx.u[:, j], ctx.est):
                    out.append(ctx.through_model(p, j))
            return out
        out = []
        for i in range(ctx.ny):
            for p in _centred_powers(ctx.yhat[:, i], ctx.est):
                g = np.zeros((ctx.n, ctx.ny))
                g[:, i] = p
                out.append(g)
        return out

    def _signature(self, ctx: Context) -> SignatureFit:
        """The linearised refit of each site's regressors (rigd.effects.linearised: beyond
        what the base's own parameters absorb — a linear fit takes a saturating valve into a
        wrong gain and time constants); the site with the larger share is named."""
        fits = {site: joint_signature(ctx, self._regs(ctx, site)) for site in SITES}
        site = max(SITES, key=lambda s: fits[s].score_est)
        sig = fits[site]
        sig.extra["site"] = site
        sig.extra["score_est_by_site"] = {s: float(fits[s].score_est) for s in SITES}
        return sig

    def regressors(self, ctx):
        return self._regs(ctx, self.signature(ctx).extra["site"])

    def reveal(self, ctx: Context) -> CannotReveal | None:
        def nominal():
            noms = []
            for j in range(ctx.nu):  # input site: the nominal curve on the input's spread
                s = _spread(ctx.u[ctx.est, j])
                noms.append(ctx.through_model(NOMINAL_BEND * _centred_powers(
                    ctx.u[:, j], ctx.est)[1] / s ** 2, j))
            for i in range(ctx.ny):
                s = _spread(ctx.yhat[ctx.est, i])
                g = np.zeros((ctx.n, ctx.ny))
                g[:, i] = NOMINAL_BEND * _centred_powers(ctx.yhat[:, i], ctx.est)[1] / s ** 2
                noms.append(g)
            return noms

        return self.reveal_at_nominal(ctx, nominal, 2, "too_small",
                                      {"nominal_share": NOMINAL_BEND})

    def evidence(self, ctx, sig):
        """Evidence code (the site: ``static_nonlinearity.input`` / ``.output``) and numbers
        (worded by rigd.diagnose.wording)."""
        site = sig.extra.get("site", "input")
        beta = np.asarray(sig.beta, float).reshape(-1, 2)
        xs = ctx.u[ctx.est] if site == "input" else ctx.yhat[ctx.est]
        # how much the fitted curve bends the signal at its spread: (a2 s² + a3 s³) / s
        bend = [float(abs(b[0]) * _spread(xs[:, k]) + abs(b[1]) * _spread(xs[:, k]) ** 2)
                for k, b in enumerate(beta)]
        k = int(np.argmax(bend)) if bend else 0
        return f"static_nonlinearity.{site}", {
            "site": site, "channel": ctx.label(k, "in" if site == "input" else "out"),
            "bend_at_spread": bend, "coefficients": beta.tolist(),
            "score_est_by_site": sig.extra.get("score_est_by_site", {})}

    # --- extension ----------------------------------------------------------------------
    def param_names(self, base):
        ny, nu = dims(base)
        return ([f"sn_in{k}_{j}" for j in range(nu) for k in (2, 3)]
                + [f"sn_out{k}_{i}" for i in range(ny) for k in (2, 3)])

    def _spreads(self, base, rec):
        ny, nu = dims(base)
        su = np.resize(np.asarray(rec.u_spread, float), nu)
        sy = np.resize(np.asarray(rec.y_spread, float), ny)
        return np.maximum(np.concatenate([su, sy]), 1e-300)

    def param_typical(self, base, rec):
        s = self._spreads(base, rec)
        return np.concatenate([[1.0 / v, 1.0 / v ** 2] for v in s])

    def record_bounds(self, base, rec):
        t = MAX_BEND * self.param_typical(base, rec)
        return -t, t

    def warm_start(self, ctx, sig):
        site = sig.extra.get("site", "input")
        beta = np.asarray(sig.beta, float)
        z_in, z_out = np.zeros(2 * ctx.nu), np.zeros(2 * ctx.ny)
        if site == "input":
            z_in = beta
        else:
            z_out = beta
        return np.concatenate([z_in, z_out])

    def refit_fixed(self, ext, sig=None) -> list[str]:
        """The site the signature did not choose stays at 0 in the diagnosis refit."""
        if sig is None or "site" not in sig.extra:
            return []
        other = "sn_out" if sig.extra["site"] == "input" else "sn_in"
        return [n for n in ext.names if n.startswith(other)]

    def input_block(self, u, theta_e, data):
        """u'_j = u_j + a2_j u_j² + a3_j u_j³ (the input site's coefficients)."""
        nu = u.shape[1]
        a = np.asarray(theta_e, float)[:2 * nu].reshape(nu, 2)
        return u + a[:, 0] * u ** 2 + a[:, 1] * u ** 3 if np.any(a) else u

    def output_block(self, y, theta_e, data):
        """y_i + c2_i y_i² + c3_i y_i³ (the output site's coefficients)."""
        nu = np.asarray(data.inputs).shape[1]
        c = np.asarray(theta_e, float)[2 * nu:].reshape(y.shape[1], 2)
        return y + c[:, 0] * y ** 2 + c[:, 1] * y ** 3


def _spread(x: np.ndarray) -> float:
    from rigd.effects._signals import spread

    return max(float(np.asarray(spread(np.asarray(x, float).reshape(-1, 1)))[0]), 1e-300)
