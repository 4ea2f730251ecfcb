"""``cubic_stiffness``: film stiffening at large eccentricity (Duffing oscillator).

m p̈ + d ṗ + k p + k3 p³ = b u. Signature: the residual is explained by the linear model's
response to p̂³ (the first-order change for a small k3) and grows with amplitude.
Extension: a cubic force −k3_i p_i³ on each axis and, with two or more axes, −k3c_i
(Σ_{j≠i} p_j²) p_i (film stiffening grows with the eccentricity |p|: k3c = k3 is the radial
law k3 |p|² p), mass-normalised, output unit⁻² s⁻²; integrated by the mechanical simulator
(the state block ``MechanicalFeedback.k3``/``k3_cross``, RK4); a base without [p, ṗ] states
is not offered it.
"""

from __future__ import annotations

import numpy as np

from rigd.effects import numbers as N
from rigd.effects.base import STRUCTURAL, Effect, dims
from rigd.ident.feedback import MechanicalFeedback


def amplitude_profile(ctx, nbins: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Residual RMS by amplitude quantile bin of |ŷ| (validation part): (edges, rms)."""
    a = np.abs(ctx.yhat[ctx.val]).max(axis=1)
    r = np.sqrt(np.mean(ctx.residual[ctx.val] ** 2, axis=1))
    edges = np.quantile(a, np.linspace(0, 1, nbins + 1))
    idx = np.clip(np.searchsorted(edges, a, side="right") - 1, 0, nbins - 1)
    rms = np.array([np.sqrt(np.mean(r[idx == b] ** 2)) if np.any(idx == b) else 0.0
                    for b in range(nbins)])
    return edges, rms


class CubicStiffness(Effect):
    name = "cubic_stiffness"
    sites = ("state",)
    requires = ("mechanical",)
    domains = STRUCTURAL  # a restoring force
    submodels = ("bearing", "generic")
    physics = "stiffness that grows with amplitude (cubic, Duffing)"
    linear_note = ("k₃p³ has no first-order term at the equilibrium p = 0")

    def regressors(self, ctx):
        p = ctx.yhat - ctx.yhat[ctx.est].mean(axis=0)
        regs = [ctx.through_force(p[:, i] ** 3, i) for i in range(ctx.ny)]
        if ctx.ny > 1:
            r2 = np.sum(p ** 2, axis=1)
            regs += [ctx.through_force((r2 - p[:, i] ** 2) * p[:, i], i) for i in range(ctx.ny)]
        return regs

    def explain(self, ctx, sig):
        edges, rms = amplitude_profile(ctx)
        ratio = float(rms[-1] / rms[0]) if rms[0] > 0 else float("inf")
        k3 = -np.asarray(sig.beta, float)[:ctx.ny]
        ev = {"k3": k3.tolist(), "k3_cross": (-np.asarray(sig.beta, float)[ctx.ny:]).tolist(),
              "residual_rms_by_amplitude": rms.tolist(),
              "amplitude_edges": edges.tolist(), "large_over_small": ratio}
        sign = "stiffening" if np.sum(k3) > 0 else "softening"
        return (f"the error grows with amplitude: residual RMS {ratio:.1f}× larger in the top "
                f"amplitude quarter (|p| > {edges[-2]:.3g}) than in the bottom one, and the "
                f"residual follows the model response to p³: a cubic {sign} stiffness "
                f"({'film stiffening at large eccentricity / ' if N.is_rotor(ctx) else ''}"
                f"Duffing); explains {N.share(sig.score)} of the residual", ev)

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        ny, _ = dims(base)
        return ([f"k3_{i + 1}" for i in range(ny)]
                + ([f"k3c_{i + 1}" for i in range(ny)] if ny > 1 else []))

    def theta0_effect(self, base, data):
        """A small stiffening (1 % of the linear force at one std of the output) as the start,
        so the fit has a scale for k3: 0.01 (2π f_peak)² / var(y)."""
        from scipy import signal as sg

        y = np.asarray(data.outputs, float)
        fs = float(data.fs)
        out = []
        for i in range(y.shape[1]):
            f, p = sg.welch(y[:, i] - y[:, i].mean(), fs=fs, nperseg=min(len(y), 1024))
            fp = max(f[int(np.argmax(p[1:])) + 1], fs / len(y))
            out.append(0.01 * (2 * np.pi * fp) ** 2 / max(np.var(y[:, i]), 1e-300))
        return np.asarray(out + ([0.0] * len(out) if len(out) > 1 else []))

    def warm_start(self, ctx, sig):
        return -np.asarray(sig.beta, float)

    def state_block(self, theta_e, data):
        """The cubic force k3_i p_i³ (+ k3c_i (Σ_{j≠i} p_j²) p_i) fed back into the base."""
        th = np.asarray(theta_e, float)
        ny = th.size // 2 if th.size > 1 else 1
        return MechanicalFeedback(k3=th[:ny], k3_cross=th[ny:] if th.size > ny else None)
