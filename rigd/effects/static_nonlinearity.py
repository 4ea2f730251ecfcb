"""``static_nonlinearity``: a static curve at the input (Hammerstein), the output (Wiener) or
fed back into the states (Lur'e).

A valve or sensor characteristic, a titration curve, a saturation-like gain: the linear model
is right but a static function bends the signal before it (input site) or after it (output
site). Posed as a polynomial of degree :attr:`StaticNonlinearity.degree` (3) on each input
and each output (its own curve per output on a MIMO record),

    u'_j = u_j + a2_j u_j² + a3_j u_j³,     y_i = ŷ_i + c2_i ŷ_i² + c3_i ŷ_i³,

the block form of a Hammerstein–Wiener model (input blocks → base → output blocks). On the
general LTI base a third site carries a curve *inside* the dynamics (a rate that depends on a
level: a reaction speeding up with temperature): one curve of each input and each model
output fed back into the states, ẋ = A x + B u + F φ(u, ŷ) (:mod:`rigd.effects.lure`), where
its parameters (states × signals × (degree − 1)) number at most :data:`MAX_STATE_PARAMS`.

Signature: the linearised refit (:mod:`rigd.effects.linearised`) of the base model's response
to the input's square and cube (input site) and of the square and cube of the model output
(output site), each together with the base model's own sensitivities (a linear fit absorbs a
strong curve into a wrong gain and time constants; the residual alone then barely shows it);
the site whose regressors add more (estimation part) is the one named (``site`` in the
finding) and refitted, the other sites' coefficients stay at 0. The state site, whose
regressors (each term fed into each state) span the input site's and more, is refitted
beside it when its F test is below rigd.ident.thresholds.P_LEVEL, and named instead when
its refit fits the held-out part better by rigd.ident.thresholds.MIN_FIT_GAIN points (the
rule of every structural choice; a strong feedback's first-order share is no guide).
``rigd identify --add static_nonlinearity`` fits every site the base carries. Parameters are
in the signals' units; their step sizes and bounds are relative to the record's spreads
(:class:`rigd.effects.scales.RecordScale`).
"""

from __future__ import annotations

import numpy as np

from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.linearised import joint_signature
from rigd.effects.lure import simulate_lure, state_responses, terms
from rigd.effects.signature import SignatureFit
from rigd.ident.model import base_of
from rigd.ident.simulate import shift_inputs
from rigd.ident.thresholds import P_LEVEL

#: largest |coefficient| × spread^(k−1): the curve may bend the signal by a few times its
#: own size over its range, not more
MAX_BEND = 5.0
#: nominal size for "cannot tell": a curve bending the signal by this share at its spread
NOMINAL_BEND = 0.1
SITES = ("input", "output")
#: the site name of a curve at the input *and* one at the output (Hammerstein–Wiener)
BOTH = "input+output"
#: most parameters of the state site (states × signals × (degree − 1)); a larger base does
#: not carry it: each parameter costs one simulation per Jacobian of every refit
MAX_STATE_PARAMS = 64
#: scales of the state site's first-order coefficients tried as the refit's start
SHRINK = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.0)


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
    sites = ("input", "output", "state")
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

    # --- the state site ------------------------------------------------------------------
    def state_carried(self, base) -> bool:
        """True when ``base`` carries the state site: a general LTI base (its ``matrices``
        and ``linear_part``) whose block has at most :data:`MAX_STATE_PARAMS` parameters."""
        b = base_of(base)
        if b.kind != "lti":   # a general LTI base (its ``matrices``)
            return False
        ny, nu = dims(b)
        return int(b.nx) * (nu + ny) * (self.degree - 1) <= MAX_STATE_PARAMS

    @staticmethod
    def _state_centres(ctx: Context):
        """(base's linear part at ``ctx.theta``, its delayed inputs, centres cu, cy): the
        estimation-part means of the delayed inputs and of the model output."""
        base = base_of(ctx.structure)
        lp = base.linear_part(np.asarray(ctx.theta, float)[:len(base.names)])
        us = shift_inputs(np.ascontiguousarray(ctx.u, float), lp.delays)
        return lp, us, np.mean(us[ctx.est], axis=0), np.mean(ctx.yhat[ctx.est], axis=0)

    def _state_regs(self, ctx: Context) -> list[np.ndarray]:
        """The first-order regressors of F: each term of φ on ``ctx`` (powers of the delayed
        inputs and of the model output about their centres, rigd.effects.lure) fed into each
        state of the base."""
        lp, us, cu, cy = self._state_centres(ctx)
        cols = [(us[:, c] - cu[c] if kind == "u" else ctx.yhat[:, c] - cy[c]) ** k
                for kind, c, k in terms(ctx.nu, ctx.ny, self.degree)]
        G = state_responses(lp, np.column_stack(cols), ctx.fs)
        return [G[:, :, t] for t in range(G.shape[-1])]

    # --- signature --------------------------------------------------------------------
    def _regs(self, ctx: Context, site: str) -> list[np.ndarray]:
        if site == "state":
            return self._state_regs(ctx)
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
        wrong gain and time constants); the input or output site with the larger share is
        named. The alternatives the refit decides on (``extra["alternatives"]``,
        :meth:`refit_alternatives`), each when its regressors pass the F test: both block
        sites at once (Hammerstein–Wiener, :data:`BOTH`), and the state site where the base
        carries it."""
        regs = {site: self._regs(ctx, site) for site in SITES}
        fits = {site: joint_signature(ctx, regs[site]) for site in SITES}
        site = max(SITES, key=lambda s: fits[s].score_est)
        alternatives = []
        both = joint_signature(ctx, regs["input"] + regs["output"])
        fits[BOTH] = both
        if both.f_p < P_LEVEL:
            both.extra.update(site=BOTH, refines=True)
            alternatives.append(both)
        if self.state_carried(ctx.structure):
            st = joint_signature(ctx, self._state_regs(ctx))
            fits["state"] = st
            if st.f_p < P_LEVEL:
                st.extra["site"] = "state"
                alternatives.append(st)
        sig = fits[site]
        sig.extra["site"] = site
        sig.extra["alternatives"] = alternatives
        shares = {s: float(f.score_est) for s, f in fits.items()}
        for f in [sig] + alternatives:
            f.extra["score_est_by_site"] = shares
        return sig

    def refit_alternatives(self, ctx: Context, sig: SignatureFit) -> list[SignatureFit]:
        """Other sites the diagnosis refits beside the signature's, in order: both block
        sites (only when the first site's refit gained MIN_FIT_GAIN points: ``refines``),
        then the state site; each named instead when its refit fits the held-out part
        better than the one kept so far by MIN_FIT_GAIN points (a first-order share misleads:
        a strong curve or feedback linearises poorly)."""
        return list(sig.extra.get("alternatives", []))

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
        """Evidence code (the site: ``static_nonlinearity.input`` / ``.output`` / ``.state``)
        and numbers (worded by rigd.diagnose.wording)."""
        site = sig.extra.get("site", "input")
        if site == "state":
            return "static_nonlinearity.state", self._state_evidence(ctx, sig)
        beta = np.asarray(sig.beta, float).reshape(-1, self.degree - 1)
        xs = {"input": ctx.u[ctx.est], "output": ctx.yhat[ctx.est],
              BOTH: np.hstack([ctx.u[ctx.est], ctx.yhat[ctx.est]])}[site]
        labels = ([ctx.label(j, "in") for j in range(ctx.nu)] if site != "output" else [])
        labels += [ctx.label(i, "out") for i in range(ctx.ny)] if site != "input" else []
        # how much the fitted curve bends the signal at its spread: Σ |a_p| s^p / s
        bend = [float(sum(abs(c) * _spread(xs[:, k]) ** (p + 1) for p, c in enumerate(b)))
                for k, b in enumerate(beta)]
        k = int(np.argmax(bend)) if bend else 0
        code = "input_output" if site == BOTH else site
        return f"static_nonlinearity.{code}", {
            "site": site, "channel": labels[k], "channels": labels,
            "bend_at_spread": bend, "coefficients": beta.tolist(),
            "score_est_by_site": sig.extra.get("score_est_by_site", {})}

    def _state_evidence(self, ctx, sig) -> dict:
        """Numbers of the state site: each signal's share of the fitted feedback's response
        (estimation part, outputs weighted 1/std), the largest named as ``channel``."""
        regs = self._state_regs(ctx)
        beta = np.asarray(sig.beta, float)
        nt = (ctx.nu + ctx.ny) * (self.degree - 1)
        w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
        labels = ([ctx.label(j, "in") for j in range(ctx.nu)]
                  + [ctx.label(i, "out") for i in range(ctx.ny)])
        energy = []
        for v in range(ctx.nu + ctx.ny):
            idx = [s * nt + v * (self.degree - 1) + q for s in range(len(regs) // nt)
                   for q in range(self.degree - 1)]
            r = sum(beta[t] * regs[t] for t in idx)
            energy.append(float(np.sum((np.asarray(r)[ctx.est] * w) ** 2)))
        tot = sum(energy) or 1.0
        k = int(np.argmax(energy))
        return {"site": "state", "channel": labels[k],
                "signal_share": {lab: e / tot for lab, e in zip(labels, energy)},
                "states": len(regs) // nt,
                "score_est_by_site": sig.extra.get("score_est_by_site", {})}

    # --- extension ----------------------------------------------------------------------
    def _layout(self, base) -> tuple[int, int, int, int]:
        """(nu, ny, states of the state site (0: not carried), terms of φ)."""
        ny, nu = dims(base)
        nx = int(base_of(base).nx) if self.state_carried(base) else 0
        return nu, ny, nx, (nu + ny) * (self.degree - 1)

    def param_names(self, base):
        nu, ny, nx, _ = self._layout(base)
        ks = range(2, self.degree + 1)
        names = ([f"sn_in{k}_{j}" for j in range(nu) for k in ks]
                 + [f"sn_out{k}_{i}" for i in range(ny) for k in ks])
        if nx:
            names += ([f"sn_cu_{j}" for j in range(nu)] + [f"sn_cy_{i}" for i in range(ny)]
                      + [f"sn_st{k}_{kind}{c}_x{s}" for s in range(nx)
                         for kind, c, k in terms(nu, ny, self.degree)])
        return names

    def fixed_names(self, base) -> list[str]:
        """The state site's centres (the estimation part's means): never fitted."""
        return [n for n in self.param_names(base) if n.startswith(("sn_cu_", "sn_cy_"))]

    def theta0_effect(self, base, data):
        """Zero curves; the state site's centres at the means of ``data``'s inputs and
        outputs."""
        nu, ny, nx, nt = self._layout(base)
        th = np.zeros(len(self.param_names(base)))
        if nx:
            m = (nu + ny) * (self.degree - 1)
            us = shift_inputs(np.ascontiguousarray(data.u, float), base_of(base).delays)
            th[m:m + nu] = np.mean(us, axis=0)
            th[m + nu:m + nu + ny] = np.mean(np.asarray(data.y, float), axis=0)
        return th

    def _spreads(self, base, rec):
        ny, nu = dims(base)
        su = np.resize(np.asarray(rec.u_spread, float), nu)
        sy = np.resize(np.asarray(rec.y_spread, float), ny)
        return np.maximum(np.concatenate([su, sy]), 1e-300)

    def param_typical(self, base, rec):
        """Curves: 1 / spread^(k−1); centres: the spread; the state site's F: a term at the
        signal's spread moving a state (output units, C's fixed 1) by 1 % of the mean output
        spread per sample."""
        s = self._spreads(base, rec)
        curves = np.concatenate([[1.0 / v ** (k - 1) for k in range(2, self.degree + 1)]
                                 for v in s])
        nu, ny, nx, nt = self._layout(base)
        if not nx:
            return curves
        per = np.concatenate([[1.0 / v ** k for k in range(2, self.degree + 1)] for v in s])
        F = np.tile(0.01 * float(np.mean(s[nu:])) * rec.fs * per, nx)
        return np.concatenate([curves, s, F])

    def record_bounds(self, base, rec):
        """Curves bend a signal by at most :data:`MAX_BEND` times its size at its spread;
        the centres and the state site's F are unbounded (a runaway loop is a failed
        simulation, the fit's penalty)."""
        t = MAX_BEND * self.param_typical(base, rec)
        m = (sum(dims(base))) * (self.degree - 1)
        t[m:] = np.inf
        return -t, t

    def warm_start(self, ctx, sig):
        site = sig.extra.get("site", "input")
        beta = np.asarray(sig.beta, float)
        th = self.theta0_effect(ctx.structure, ctx.data)
        m = self.degree - 1
        nu, ny, nx, _ = self._layout(ctx.structure)
        if site == "input":
            th[:m * nu] = beta
        elif site == "output":
            th[m * nu:m * (nu + ny)] = beta
        elif site == BOTH:
            th[:m * (nu + ny)] = beta
        if nx:
            c = m * (nu + ny)
            _, _, th[c:c + nu], th[c + nu:c + nu + ny] = self._state_centres(ctx)
            if site == "state":
                th[c + nu + ny:] = beta
                th = self._shrunk(ctx, th, c + nu + ny)
        return th

    def _shrunk(self, ctx, th: np.ndarray, first: int) -> np.ndarray:
        """``th`` with its state-site F scaled by the α of :data:`SHRINK` whose simulation
        fits the estimation part best: the first-order coefficients of a strong feedback
        overshoot, and a loop that runs away gives the fit nothing to descend (α = 0: the
        base itself)."""
        ext = self.extend(ctx.structure)
        w = 1.0 / np.maximum(np.std(ctx.y[ctx.est], axis=0), 1e-300)
        best, best_cost = th.copy(), np.inf
        for a in SHRINK:
            t = th.copy()
            t[first:] *= a
            with np.errstate(all="ignore"):
                yh = np.asarray(ext.simulate(np.concatenate([ctx.theta, t]), ctx.data), float)
            cost = float(np.sum(((ctx.y[ctx.est] - yh[ctx.est]) * w) ** 2))
            if np.isfinite(cost) and cost < best_cost:
                best, best_cost = t, cost
        return best

    def refit_fixed(self, ext, sig=None) -> list[str]:
        """The sites the signature did not choose stay at 0 in the diagnosis refit."""
        if sig is None or "site" not in sig.extra:
            return []
        keep = {"input": ("sn_in",), "output": ("sn_out",), BOTH: ("sn_in", "sn_out"),
                "state": ("sn_st",)}[sig.extra["site"]]
        return [n for n in ext.names if n.startswith(("sn_in", "sn_out", "sn_st"))
                and not n.startswith(keep)]

    def input_block(self, u, theta_e, data):
        """u'_j = u_j + a2_j u_j² + … + a_D,j u_j^D (the input site's coefficients)."""
        nu, m = u.shape[1], self.degree - 1
        a = np.asarray(theta_e, float)[:m * nu].reshape(nu, m)
        return _poly(u, a) if np.any(a) else u

    def output_block(self, y, theta_e, data):
        """y_i + c2_i y_i² + … + c_D,i y_i^D (the output site's coefficients)."""
        nu, m = np.asarray(data.inputs).shape[1], self.degree - 1
        c = np.asarray(theta_e, float)[m * nu:m * (nu + y.shape[1])].reshape(y.shape[1], m)
        return _poly(y, c) if np.any(c) else y

    # --- the state site (rigd.effects.lure) --------------------------------------------------
    def state_block(self, theta_e, data):
        """None: the state site is simulated by :meth:`state_simulate`."""
        return None

    def owns_state(self, base) -> bool:
        """The state site needs the model simulated by :meth:`state_simulate`."""
        return self.state_carried(base)

    def state_simulate(self, base, theta_b, theta_e, feedback, data):
        """The base with the state site's block (rigd.effects.lure); the base's own
        simulation when F = 0."""
        nu, ny, nx, nt = self._layout(base)
        c = (nu + ny) * (self.degree - 1)
        te = np.asarray(theta_e, float)
        F = te[c + nu + ny:].reshape(nx, nt) if nx else None
        if F is None or not np.any(F):
            return (base.simulate(theta_b, data) if feedback is None
                    else base.simulate(theta_b, data, feedback))
        mats = base.matrices(theta_b)
        return simulate_lure(base.linear_part(theta_b), mats["x0"], mats["yoff"], F,
                             te[c:c + nu], te[c + nu:c + nu + ny], self.degree, data.u,
                             data.fs)


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
