"""``runout``: mass unbalance and surface run-out, locked to the shaft angle φ.

Signature: residual coherent with cos/sin(k·φ), k = 1, 2 (per output). Extension: an additive
output term Σ_k a_ik cos(kφ) + b_ik sin(kφ) — the run-out filter F_r(φ) of the paper's §4.4
identified together with the model instead of from a separate run-out record.

Can the record tell: without a shaft angle column, no (a structural rule). With one, by
detectability (rigd.effects.detectability): a 1× run-out of 10 % of each output's rms on the
recorded angle must stay detectable after what the base model and an offset would absorb. At
standstill (Ω = 0) φ is constant, the run-out an offset: all absorbed, cannot tell.
"""

from __future__ import annotations

import numpy as np

from rigd.effects import detectability as DT
from rigd.effects import numbers as N
from rigd.effects.base import STRUCTURAL, Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.ident.iddata import get_phi

HARMONICS = (1, 2)
#: nominal 1× run-out for "can the record tell", share of each output's rms
NOMINAL_SHARE = 0.10


def harmonics(phi: np.ndarray) -> list[np.ndarray]:
    """[cos φ, sin φ, cos 2φ, sin 2φ]."""
    out = []
    for k in HARMONICS:
        out += [np.cos(k * phi), np.sin(k * phi)]
    return out


class Runout(Effect):
    name = "runout"
    sites = ("output",)
    #: its output block is y + g(u, θ): the base's output sensitivities hold through it
    additive_output = True
    requires = ("rotation",)
    domains = STRUCTURAL  # a shaft that may turn: not a process plant
    submodels = ("bearing", "generic")
    physics = "mass unbalance or surface run-out locked to the shaft angle"
    linear_note = ("exogenous (harmonics of the shaft angle): no path from the inputs")

    def reveal(self, ctx: Context) -> CannotReveal | None:
        phi = ctx.phi
        if phi is None:
            if not N.is_rotor(ctx):  # a record from another rig: no rotor words
                return CannotReveal(self.name, "the record carries no rotation angle (no "
                                    "'phi' column)", "if a part of the structure rotates, "
                                    "record its angle as a 'phi' column", ctx.submodel)
            return CannotReveal(self.name, "the record carries no shaft angle phi",
                                "record the encoder angle phi at shaft speed > 0",
                                ctx.submodel)
        turns = np.sum(np.abs(np.diff(np.unwrap(phi)))) / (2 * np.pi)
        amp = NOMINAL_SHARE * np.std(ctx.y, axis=0)
        sigs = [np.outer(f(phi), amp) for f in (np.cos, np.sin)]
        d, _ = DT.best(ctx, sigs, k=len(HARMONICS) * 2 * ctx.ny)
        # an angle-locked signature the base model absorbs whole (a constant φ: an offset)
        # cannot be seen in the residual either
        if d.detectable or (d.absorbed < 0.999 and DT.seen(ctx, self.signature(ctx))):
            return None
        size = f"a 1× response of {100 * NOMINAL_SHARE:.0f} % of the output"
        if not N.is_rotor(ctx):
            return CannotReveal(self.name, f"the angle phi turned {turns:.1f} times: {size}, "
                                f"locked to it, would not show ({d.describe()})",
                                "record while the part rotates several turns", ctx.submodel)
        return CannotReveal(self.name, f"the shaft turned {turns:.1f} times (Ω = "
                            f"{60 * ctx.omega_hz:.0f} rpm): {size} (run-out) would not show "
                            f"({d.describe()})",
                            "re-run at Ω > 0 (e.g. 3000 rpm) or add a run-out record "
                            "(--runout)", ctx.submodel)

    def regressors(self, ctx: Context) -> list[np.ndarray]:
        regs = []
        for h in harmonics(ctx.phi):
            for i in range(ctx.ny):
                g = np.zeros((ctx.n, ctx.ny))
                g[:, i] = h
                regs.append(g)
        return regs

    def explain(self, ctx, sig):
        b = sig.beta.reshape(len(HARMONICS), 2, ctx.ny)  # (k, cos/sin, output)
        amp = np.hypot(b[:, 0], b[:, 1])  # (k, ny)
        k, i = np.unravel_index(np.argmax(amp), amp.shape)
        order = HARMONICS[k]
        ev = {"order": int(order), "amplitude": float(amp[k, i]), "output": ctx.label(i),
              "frequency_hz": float(order * ctx.omega_hz),
              "amplitudes": {f"{HARMONICS[a]}x": {ctx.label(j): float(amp[a, j])
                                                  for j in range(ctx.ny)}
                             for a in range(len(HARMONICS))}}
        unit = " µm" if ctx.submodel == "bearing" else ""
        return (f"{amp[k, i]:.3g}{unit} on {ctx.label(i)} at {order}× shaft speed "
                f"({order * ctx.omega_hz:.1f} Hz), locked to the encoder angle: "
                f"{'mass unbalance or run-out' if order == 1 else 'run-out (out-of-roundness)'}"
                f"; it explains {100 * sig.score:.0f} % of the residual", ev)

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        ny, _ = dims(base)
        return [f"runout_{ab}{k}_{i}" for k in HARMONICS for ab in ("a", "b")
                for i in range(ny)]

    def warm_start(self, ctx, sig):
        return np.asarray(sig.beta, float)

    def output_block(self, y, theta_e, data):
        """y + Σ_k (a_k cos kφ + b_k sin kφ) of the shaft angle φ (none without φ)."""
        phi = get_phi(data)
        if phi is None:
            return y
        c = np.asarray(theta_e).reshape(len(HARMONICS) * 2, y.shape[1])
        return y + np.column_stack(harmonics(phi)) @ c
