"""``hysteresis`` at the restoring-force site: a Bouc–Wen hysteretic stiffness in the structure.

In joints, dampers, rubber mounts and bolted structures the hysteresis is in the restoring
force, not in the actuator: the mass-normalised model becomes

    p̈ + D ṗ + K p + a ∘ (z − c p) = B u,     ż = c (ṗ − β |ṗ| z − γ ṗ |z|)   (Bouc–Wen, ν = 1)

per axis, with z dimensionless, c per output unit (its start values are set per output
standard deviation σ_p of the record, c = c_n/σ_p, so nothing depends on the units),
a its force per unit (acceleration, output units / s²); small motions give z ≈ c p, whose
linear force is in K already — hence z − c p: the linear fit stays the start and a measures
the *loop*), β, γ the loop shape (β + γ > 0: the loop
saturates; < 0: it widens with amplitude — the Bouc–Wen benchmark's δ < −γ). Integrated by a
compiled RK4 with sub-steps (input held or linear between samples like the base).

Signature: the linear model's response to a force a·z(p̂) with z the operator of the
simulated motion, for loop shapes of both classes of the ν = 1 law (:data:`SHAPES`); the
refit starts from the best, with the redundant loop scale c kept there
(:meth:`refit_fixed`). Reported as ``hysteresis`` with ``site: restoring force``
(``rigd identify --add hysteresis_restoring``).
"""

from __future__ import annotations

import numba
import numpy as np

from rigd.effects.base import STRUCTURAL, Effect, dims
from rigd.effects.context import Context
from rigd.effects.signature import SignatureFit, signature_fit

#: (c·σ_p, β, γ) loop shapes tried by the signature (c per output standard deviation): both
#: classes of the ν = 1 law at three loop scales — β + γ > 0 (the loop saturates: softening;
#: (0.5, 0.5), (1.5, −1)) and β + γ < 0 < β − γ (the loop widens with amplitude: hardening,
#: as in the Bouc–Wen benchmark's δ < −γ; (0.5, −1))
SHAPES = tuple((c, b, g) for c in (1.0, 0.3, 3.0)
               for b, g in ((0.5, 0.5), (1.5, -1.0), (0.5, -1.0)))


@numba.njit(cache=True)
def bw_operator(p: np.ndarray, c: float, beta: float, gamma: float, sig: float) -> np.ndarray:
    """z(p) of the Bouc–Wen law driven by the sequence ``p`` (n,) (RK4 on each step)."""
    n = p.shape[0]
    z = np.zeros(n)
    zz = 0.0
    for k in range(1, n):
        dp = (p[k] - p[k - 1]) / sig
        h = 1.0
        # ż per unit of "time" with ṗ_n = dp (one step)
        k1 = c * (dp - beta * abs(dp) * zz - gamma * dp * abs(zz))
        z2 = zz + 0.5 * h * k1
        k2 = c * (dp - beta * abs(dp) * z2 - gamma * dp * abs(z2))
        z3 = zz + 0.5 * h * k2
        k3 = c * (dp - beta * abs(dp) * z3 - gamma * dp * abs(z3))
        z4 = zz + h * k3
        k4 = c * (dp - beta * abs(dp) * z4 - gamma * dp * abs(z4))
        zz = zz + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.isfinite(zz) or abs(zz) > 1e6:
            zz = 1e6 if zz > 0 else -1e6
        z[k] = zz
    return z


@numba.njit(cache=True, inline="always")
def _deriv(K, D, a, c, beta, gamma, sig, k3, k3c, p, v, z, f, out_a, out_z):
    m = p.shape[0]
    pp = 0.0
    for j in range(m):
        pp += p[j] * p[j]
    for i in range(m):
        s = (f[i] - a[i] * (z[i] - c[i] * p[i]) - k3[i] * p[i] * p[i] * p[i]
             - k3c[i] * (pp - p[i] * p[i]) * p[i])
        for j in range(m):
            s -= K[i, j] * p[j] + D[i, j] * v[j]
        out_a[i] = s
        vn = v[i] / sig[i]
        out_z[i] = c[i] * (vn - beta[i] * abs(vn) * z[i] - gamma[i] * vn * abs(z[i]))


@numba.njit(cache=True)
def bw_kernel(K, D, B, a, c, beta, gamma, sig, k3, k3c, x0, u, dt, nsub,
              foh):  # pragma: no cover
    """p̈ + D ṗ + K p + k3∘p³ + k3c∘(|p|² − p²)∘p + a∘(z − c p) = B u,
    ż = c(ṗ − β|ṗ|z − γ ṗ|z|) (ṗ per ``sig``); RK4 with ≥ ``nsub`` sub-steps per sample
    (more where the z law is stiff, ≤ 64)."""
    n = u.shape[0]
    m = K.shape[0]
    nu = B.shape[1]
    p = x0[:m].copy()
    v = x0[m:2 * m].copy()
    z = np.zeros(m)
    y = np.empty((n, m))
    f0 = np.empty(m)
    f1 = np.empty(m)
    f = np.empty(m)
    ka = np.empty((4, m))
    kz = np.empty((4, m))
    pt = np.empty(m)
    vt = np.empty(m)
    zt = np.empty(m)
    kv = np.empty((4, m))
    for k in range(n):
        for i in range(m):
            y[k, i] = p[i]
        # the z law is stiff at fast motion (rate c|ṗ|(1 + |β| + |γ|)): sub-steps so that
        # each moves z by a fraction of its scale
        rate = 0.0
        for i in range(m):
            rate = max(rate, c[i] * abs(v[i]) * (1.0 + abs(beta[i]) + abs(gamma[i])))
        ns = max(nsub, min(64, int(np.ceil(2.0 * rate * dt))))
        h = dt / ns
        kn = k + 1 if k + 1 < n else k
        for i in range(m):
            s0 = 0.0
            s1 = 0.0
            for j in range(nu):
                s0 += B[i, j] * u[k, j]
                s1 += B[i, j] * u[kn, j]
            f0[i] = s0
            f1[i] = s1 if foh else s0
        for q in range(ns):
            for st in range(4):
                frac = 0.0 if st == 0 else (0.5 if st < 3 else 1.0)
                tt = (q + frac) / ns
                for i in range(m):
                    f[i] = f0[i] + (f1[i] - f0[i]) * tt
                    if st == 0:
                        pt[i], vt[i], zt[i] = p[i], v[i], z[i]
                    else:
                        pt[i] = p[i] + frac * h * kv[st - 1, i]
                        vt[i] = v[i] + frac * h * ka[st - 1, i]
                        zt[i] = z[i] + frac * h * kz[st - 1, i]
                for i in range(m):
                    kv[st, i] = vt[i]
                _deriv(K, D, a, c, beta, gamma, sig, k3, k3c, pt, vt, zt, f, ka[st], kz[st])
            for i in range(m):
                p[i] += h / 6.0 * (kv[0, i] + 2 * kv[1, i] + 2 * kv[2, i] + kv[3, i])
                v[i] += h / 6.0 * (ka[0, i] + 2 * ka[1, i] + 2 * ka[2, i] + ka[3, i])
                z[i] += h / 6.0 * (kz[0, i] + 2 * kz[1, i] + 2 * kz[2, i] + kz[3, i])
            for i in range(m):
                if not np.isfinite(p[i]) or not np.isfinite(z[i]) or abs(z[i]) > 1e6:
                    y[k:, :] = np.nan
                    return y
    return y


def _nsub(K: np.ndarray, fs: float) -> int:
    """RK4 sub-steps: ≥ 2, and ≥ 8 per period of the fastest mode."""
    wmax = float(np.sqrt(max(np.max(np.abs(np.linalg.eigvals(K))), 1e-300)))
    return int(min(64, max(2, np.ceil(8 * wmax / (2 * np.pi) / fs))))


class RestoringHysteresis(Effect):
    name = "hysteresis_restoring"
    reported_as = "hysteresis"
    site = "restoring force"
    sites = ("state",)
    requires = ("mechanical",)
    #: its own RK4 kernel (bw_kernel) carries K, D, B and the cubic terms, not dry friction
    excludes = ("friction",)
    domains = STRUCTURAL  # a restoring force
    # generic records: in the default screening (docs/diagnose.md). Not offered on the
    # rotor's bearing sub-model: a gas film's force is not known to be hysteretic and no
    # rotor record has shown it; ask for it there with --effects if a record suggests it
    submodels = ("generic",)
    screened = True
    #: RK4 fits from several starts: refitted only when the signature is decisive
    costly_refit = True
    #: refitted on the first 10,000 estimation samples of a longer record (a window: on
    #: Silverbox's 39,400 its RK4 refits ran past 10 minutes under load)
    max_fit_samples = 10_000
    physics = "hysteresis in the restoring force (joints, dampers, mounts): Bouc–Wen stiffness"

    def state_block(self, theta_e, data):
        """None: the Bouc–Wen force has a state of its own (:meth:`state_simulate`)."""
        return None

    def state_simulate(self, base, theta_b, theta_e, feedback, data):
        """Output (n, ny) of the mechanical ``base`` at ``theta_b`` with the Bouc–Wen
        restoring force and the other state-level effects' ``feedback``
        (rigd.ident.feedback.MechanicalFeedback or None): :func:`bw_kernel`, the base's
        parallel modes and output offsets added."""
        if "mechanical" not in base.carries:
            raise ValueError("the restoring-force hysteresis needs a mechanical base model "
                             "(states [p, ṗ])")
        te = np.asarray(theta_e, float)
        A, Bc, _, _, x0 = base.continuous(theta_b)
        m = A.shape[0] // 2
        K, D, B = -A[m:, :m], -A[m:, m:], Bc[m:]
        fb = feedback.as_dict() if feedback is not None else {}
        # bw_kernel carries K, D, B and the cubic terms; dry friction beside it is refused,
        # never silently simulated without
        fr = fb.get("friction")
        if fr is not None and np.any(np.asarray(fr, float)[0] != 0.0):
            raise ValueError("the restoring-force hysteresis cannot be simulated with dry "
                             "friction beside it on the same base (its Bouc–Wen kernel "
                             "carries K, D, B and the cubic stiffness terms only)")
        K = K if fb.get("dK") is None else K + fb["dK"]
        D = D if fb.get("dD") is None else D + fb["dD"]
        B = B if fb.get("dB") is None else B + fb["dB"]
        k3 = np.zeros(m) if fb.get("k3") is None else np.asarray(fb["k3"], float)
        k3c = (np.zeros(m) if fb.get("k3_cross") is None
               else np.asarray(fb["k3_cross"], float))
        u = np.ascontiguousarray(data.inputs, float)
        a, c, be, ga = (np.ascontiguousarray(te[i * m:(i + 1) * m]) for i in range(4))
        y = bw_kernel(np.ascontiguousarray(K), np.ascontiguousarray(D), np.ascontiguousarray(B),
                      a, np.abs(c), be, ga, np.ones(m), np.ascontiguousarray(k3),
                      np.ascontiguousarray(k3c),
                      np.ascontiguousarray(x0, dtype=float), u, 1.0 / float(data.fs),
                      _nsub(K, float(data.fs)), base.hold == "foh")
        off = base.output_offset(theta_b)
        if off is not None:   # the outputs' zero (generic): y = p + y_off
            y = y + off
        add = base.parallel_output(theta_b, data)  # parallel modes and their free response
        y = y if add is None else y + add
        return y

    def refit_fixed(self, ext, sig=None) -> list[str]:
        """The loop scale ``c`` stays at its start in the diagnosis refit: z ↦ λz with
        (a, c, β, γ) ↦ (a/λ, cλ, β/λ, γ/λ) gives the same output (the ν = 1 law is
        homogeneous in z), so one of them is redundant; fixing c leaves the rest
        identifiable (an OE fit along the redundant direction crawled for a minute)."""
        return [n for n in ext.names if n.startswith("hr_c_")]

    def _regs(self, ctx: Context, shape) -> list[np.ndarray]:
        c, be, ga = shape
        p = ctx.yhat - ctx.yhat[ctx.est].mean(axis=0)
        sig = _sigma(ctx.y[ctx.est])
        return [ctx.through_force(-(bw_operator(np.ascontiguousarray(p[:, i]), c / sig[i], be,
                                                ga, 1.0) - c / sig[i] * p[:, i]), i)
                for i in range(ctx.ny)]

    def signature(self, ctx: Context) -> SignatureFit:
        best, shape = None, SHAPES[0]
        by_scale: dict[float, tuple[float, tuple, np.ndarray]] = {}
        for sh in SHAPES:
            s = signature_fit(ctx, self._regs(ctx, sh))
            if best is None or s.score_est > best.score_est:
                best, shape = s, sh
            if sh[0] not in by_scale or s.score_est > by_scale[sh[0]][0]:
                by_scale[sh[0]] = (s.score_est, sh, np.asarray(s.beta, float))
        best.extra = {"shape": shape, "site": self.site,
                      "by_scale": [(sh, beta) for _, sh, beta in by_scale.values()]}
        return best

    def refit_starts(self, ctx: Context, sig: SignatureFit) -> list[np.ndarray]:
        """Start values of the refit: the best loop shape of each loop scale. The first-
        order signature ranks shapes poorly when the loop is large (on the Bouc–Wen
        benchmark the best-ranked shape led the OE fit to a local minimum, the others not);
        the engine keeps the start whose fit has the lowest estimation cost."""
        ny = ctx.ny
        sigma = _sigma(ctx.y[ctx.est])
        out = []
        for (c, be, ga), beta in sig.extra.get("by_scale", []):
            out.append(np.concatenate([beta[:ny], c / sigma, np.full(ny, be),
                                       np.full(ny, ga)]))
        return out or [self.warm_start(ctx, sig)]

    def regressors(self, ctx):
        return self._regs(ctx, SHAPES[0])

    def explain(self, ctx, sig):
        j, d = direction_difference(ctx.residual, ctx.yhat)
        return (f"the residual on {ctx.label(j)} is {d:+.3g} higher after the motion last rose "
                f"than after it last fell at the same position: hysteresis in the restoring "
                f"force (a Bouc–Wen hysteretic stiffness, as in joints, dampers and mounts), "
                f"not at the input; the operator of the model's motion explains "
                f"{100 * sig.score:.0f} % of the residual",
                {"site": self.site, "reported_as": self.reported_as,
                 "shape": sig.extra.get("shape")})

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        ny, _ = dims(base)
        return [f"hr_{k}_{i + 1}" for k in ("a", "c", "beta", "gamma") for i in range(ny)]

    def theta0_effect(self, base, data):
        ny, _ = dims(base)
        c, be, ga = SHAPES[0]
        return np.concatenate([np.zeros(ny), c / _sigma(data.outputs), np.full(ny, be),
                               np.full(ny, ga)])

    def param_bounds(self, base):
        ny, _ = dims(base)
        lo = np.concatenate([np.full(ny, -np.inf), np.full(ny, 1e-300), np.full(ny, -20.0),
                             np.full(ny, -20.0)])
        hi = np.concatenate([np.full(ny, np.inf), np.full(ny, np.inf), np.full(ny, 20.0),
                             np.full(ny, 20.0)])
        return lo, hi

    def warm_start(self, ctx, sig):
        c, be, ga = sig.extra.get("shape", SHAPES[0])
        ny = ctx.ny
        return np.concatenate([np.asarray(sig.beta, float)[:ny], c / _sigma(ctx.y[ctx.est]),
                               np.full(ny, be), np.full(ny, ga)])


def _sigma(y) -> np.ndarray:
    y = np.asarray(y, float)
    return np.maximum(np.std(y, axis=0), 1e-300)


def direction_difference(r: np.ndarray, motion: np.ndarray) -> tuple[int, float]:
    """(axis, mean residual after the motion last rose − after it last fell) of the axis
    where that difference is largest (same sign convention as the input-site finding)."""
    diffs = []
    for i in range(r.shape[1]):
        s = np.sign(np.diff(motion[:, i], prepend=motion[0, i]))
        idx = np.maximum.accumulate(np.where(s != 0, np.arange(s.size), 0))
        last = s[idx]
        a, b = last > 0, last < 0
        diffs.append(float(np.mean(r[a, i]) - np.mean(r[b, i])) if a.any() and b.any()
                     else 0.0)
    j = int(np.argmax(np.abs(diffs)))
    return j, diffs[j]
