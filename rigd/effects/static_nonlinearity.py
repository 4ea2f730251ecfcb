"""``static_nonlinearity``: a static curve at the input (Hammerstein) or the output (Wiener).

A valve or sensor characteristic, a titration curve, a saturation-like gain: the linear model
is right but a static function bends the signal before it (input site) or after it (output
site). Posed as a polynomial of degree :attr:`StaticNonlinearity.degree` (3) on each input
and each output (its own curve per output on a MIMO record),

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


def _centred_powers(x: np.ndarray, est: slice, degree: int = 3) -> list[np.ndarray]:
    """[x_c², …, x_c^degree] of (n,) ``x`` centred on its estimation-part mean (x_c), each
    even power less its estimation-part mean."""
    xc = x - np.mean(x[est])
    out = []
    for k in range(2, degree + 1):
        p = xc ** k
        out.append(p - np.mean(p[est]) if k % 2 == 0 else p)
    return out


class StaticNonlinearity(Effect):
    name = "static_nonlinearity"
    site = "input/output"
    sites = ("input", "output")
    submodels = ("generic",)
    physics = "a static curve at the input or output (valve or sensor characteristic)"
    #: screened by default (issue 20: a Hammerstein or Wiener record from any lab must get
    #: it named without asking); on the cascaded tanks it is named at the input (the
    #: square-root outflows make the steady level quadratic in the pump voltage)
    screened = True
    #: polynomial degree of each curve (powers 2 … degree; 3 in the catalogue: degree 5 on
    #: the DaISy CSTR's estimation part gains 0.4–0.6 fit points there and loses on held-out
    #: data, docs/diagnose.md)
    degree = 3

    # --- signature --------------------------------------------------------------------
    def _regs(self, ctx: Context, site: str) -> list[np.ndarray]:
        if site == "input":
            out = []
            for j in range(ctx.nu):
                for p in _centred_powers(ctx.u[:, j], ctx.est, self.degree):
                    out.append(ctx.through_model(p, j))
            return out
        out = []
        for i in range(ctx.ny):
            for p in _centred_powers(ctx.yhat[:, i], ctx.est, self.degree):
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
        beta = np.asarray(sig.beta, float).reshape(-1, self.degree - 1)
        xs = ctx.u[ctx.est] if site == "input" else ctx.yhat[ctx.est]
        # how much the fitted curve bends the signal at its spread: Σ |a_p| s^p / s
        bend = [float(sum(abs(c) * _spread(xs[:, k]) ** (p + 1) for p, c in enumerate(b)))
                for k, b in enumerate(beta)]
        k = int(np.argmax(bend)) if bend else 0
        return f"static_nonlinearity.{site}", {
            "site": site, "channel": ctx.label(k, "in" if site == "input" else "out"),
            "bend_at_spread": bend, "coefficients": beta.tolist(),
            "score_est_by_site": sig.extra.get("score_est_by_site", {})}

    # --- extension ----------------------------------------------------------------------
    def param_names(self, base):
        ny, nu = dims(base)
        ks = range(2, self.degree + 1)
        return ([f"sn_in{k}_{j}" for j in range(nu) for k in ks]
                + [f"sn_out{k}_{i}" for i in range(ny) for k in ks])

    def _spreads(self, base, rec):
        ny, nu = dims(base)
        su = np.resize(np.asarray(rec.u_spread, float), nu)
        sy = np.resize(np.asarray(rec.y_spread, float), ny)
        return np.maximum(np.concatenate([su, sy]), 1e-300)

    def param_typical(self, base, rec):
        s = self._spreads(base, rec)
        return np.concatenate([[1.0 / v ** (k - 1) for k in range(2, self.degree + 1)]
                               for v in s])

    def record_bounds(self, base, rec):
        t = MAX_BEND * self.param_typical(base, rec)
        return -t, t

    def warm_start(self, ctx, sig):
        site = sig.extra.get("site", "input")
        beta = np.asarray(sig.beta, float)
        m = self.degree - 1
        z_in, z_out = np.zeros(m * ctx.nu), np.zeros(m * ctx.ny)
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
        """u'_j = u_j + a2_j u_j² + … + a_D,j u_j^D (the input site's coefficients)."""
        nu, m = u.shape[1], self.degree - 1
        a = np.asarray(theta_e, float)[:m * nu].reshape(nu, m)
        return _poly(u, a) if np.any(a) else u

    def output_block(self, y, theta_e, data):
        """y_i + c2_i y_i² + … + c_D,i y_i^D (the output site's coefficients)."""
        nu, m = np.asarray(data.inputs).shape[1], self.degree - 1
        c = np.asarray(theta_e, float)[m * nu:].reshape(y.shape[1], m)
        return _poly(y, c)


def _poly(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """x + Σ_k c[:, k−2] x^k, k = 2 … degree, per column of (n, m) ``x`` (``c`` (m, degree−1))."""
    out, p = x.copy(), x
    for k in range(c.shape[1]):
        p = p * x
        out = out + c[:, k] * p
    return out


def _spread(x: np.ndarray) -> float:
    from rigd.effects._signals import spread

    return max(float(np.asarray(spread(np.asarray(x, float).reshape(-1, 1)))[0]), 1e-300)
