"""``static_nonlinearity``: a static curve at the input (Hammerstein) or the output (Wiener).

A valve or sensor characteristic, a titration curve, a saturation-like gain: the linear model
is right but a static function bends the signal before it (input site) or after it (output
site). Posed as a polynomial of degree 3 on each input and each output,

    u'_j = u_j + a2_j u_j² + a3_j u_j³,     y_i = ŷ_i + c2_i ŷ_i² + c3_i ŷ_i³,

the block form of a Hammerstein–Wiener model (input blocks → base → output blocks).

Signature: the residual is regressed on the base model's response to the input's square and
cube (input site) and on the square and cube of the model output (output site); the site whose
regressors explain more of the residual (estimation part) is the one named (``site`` in the
finding) and refitted, the other site's coefficients stay at 0. ``rigd identify --add
static_nonlinearity`` fits both sites. Parameters are in the signals' units; their step sizes
and bounds are relative to the record's spreads (:class:`rigd.effects.scales.RecordScale`).
"""

from __future__ import annotations

import numpy as np

from rigd.effects import detectability as DT
from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.signature import SignatureFit, signature_fit
from rigd.ident.iddata import replace_inputs

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
    level = "input"
    site = "input/output"
    submodels = ("generic",)
    #: not screened by default yet: on the cascaded tanks its output curve takes up the
    #: overflow (a saturation of the upper tank's state, not a static curve) and on a Duffing
    #: record it competed with cubic_stiffness; asked for with --effects / --add
    screened = False
    physics = "a static curve at the input or output (valve or sensor characteristic)"

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

    def signature(self, ctx: Context) -> SignatureFit:
        key = ("signature", self.name)
        if key in ctx.cache:
            return ctx.cache[key]
        fits = {site: signature_fit(ctx, self._regs(ctx, site)) for site in SITES}
        site = max(SITES, key=lambda s: fits[s].score_est)
        sig = fits[site]
        sig.extra["site"] = site
        sig.extra["score_est_by_site"] = {s: float(fits[s].score_est) for s in SITES}
        ctx.cache[key] = sig
        return sig

    def regressors(self, ctx):
        return self._regs(ctx, self.signature(ctx).extra["site"])

    def reveal(self, ctx: Context) -> CannotReveal | None:
        if DT.seen(ctx, self.signature(ctx)):
            return None
        noms = []
        for j in range(ctx.nu):  # input site: the nominal curve on the input's own spread
            s = _spread(ctx.u[ctx.est, j])
            noms.append(ctx.through_model(NOMINAL_BEND * _centred_powers(
                ctx.u[:, j], ctx.est)[1] / s ** 2, j))
        for i in range(ctx.ny):
            s = _spread(ctx.yhat[ctx.est, i])
            g = np.zeros((ctx.n, ctx.ny))
            g[:, i] = NOMINAL_BEND * _centred_powers(ctx.yhat[:, i], ctx.est)[1] / s ** 2
            noms.append(g)
        d, _ = DT.best(ctx, noms, k=2)
        if d.detectable:
            return None
        return CannotReveal(self.name, f"a static curve bending the input or the output by "
                            f"{100 * NOMINAL_BEND:.0f} % of its spread would not show on this "
                            f"record ({d.describe()})",
                            "re-run with an input that visits many levels over the whole "
                            "operating range (multi-level steps or a large multisine)",
                            ctx.submodel)

    def explain(self, ctx, sig):
        site = sig.extra.get("site", "input")
        beta = np.asarray(sig.beta, float).reshape(-1, 2)
        xs = ctx.u[ctx.est] if site == "input" else ctx.yhat[ctx.est]
        # how much the fitted curve bends the signal at its spread: (a2 s² + a3 s³) / s
        bend = [float(abs(b[0]) * _spread(xs[:, k]) + abs(b[1]) * _spread(xs[:, k]) ** 2)
                for k, b in enumerate(beta)]
        k = int(np.argmax(bend)) if bend else 0
        where = ctx.label(k, "in" if site == "input" else "out")
        ev = {"code": f"static_nonlinearity.{site}", "site": site, "channel": where,
              "bend_at_spread": bend, "coefficients": beta.tolist(),
              "score_est_by_site": sig.extra.get("score_est_by_site", {})}
        signal = "the input" if site == "input" else "the model output"
        return (f"the error is a smooth function of the level of {signal} ({where}): a static "
                f"curve at the {site} bending it by about {100 * max(bend or [0]):.0f} % at "
                f"its spread ({'Hammerstein' if site == 'input' else 'Wiener'} form); "
                f"explains {100 * sig.score:.0f} % of the residual", ev)

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

    def simulate_with(self, sim, theta_e, data, base):
        ny, nu = dims(base)
        th = np.asarray(theta_e, float)
        a = th[:2 * nu].reshape(nu, 2)
        c = th[2 * nu:].reshape(ny, 2)
        if np.any(a):
            u = np.asarray(data.inputs, float)
            y = sim(replace_inputs(data, u + a[:, 0] * u ** 2 + a[:, 1] * u ** 3))
        else:
            y = sim(data)
        y = np.asarray(y, float)
        return y + c[:, 0] * y ** 2 + c[:, 1] * y ** 3


def _spread(x: np.ndarray) -> float:
    from rigd.effects._signals import spread

    return max(float(np.asarray(spread(np.asarray(x, float).reshape(-1, 1)))[0]), 1e-300)
