"""``hysteresis``: piezo hysteresis in the valves, acting on the drive inside the valve loops.

Physics (docs/plant.md, docs/loop.md): each valve's drive v_i passes through a
rate-independent Bouc–Wen operator (n = 1, β = γ) before the stack, v' = v − h(v), and the
valve is closed by a PD loop. By superposition through the closed loop (rigd.effects._drive)

    u = H_a(s) · (r − A · (φ_c(v_+) − φ_c(v_−)) / 2)                  (Eqs. 8–10 plus h)

with H_a the actuator model (r → u), v_± the recorded drives of the axis' valve pair (Eq. 1;
the input r itself when the record has no drives), φ_c the normalised Bouc–Wen operator
(saturates at ±1; slope c per volt right after a reversal, exponential approach to ±1 at rate
c) and A the loop-suppressed half-width of the loop in units of r (≈ h_max/(kff + kp)).
A per axis and c are fitted with the rest.

Signature: the residual depends on the direction of the last motion and does not decay while
the input holds still (no drift: that is creep). The regressor is the model-filtered operator
output for the best c of a few (estimation part); the refit starts there.

Can the record tell (rigd.effects.detectability): a loop of half-width 5 % of the input's
range (full width 10 % of the stroke, typical of piezo stacks; three operator rates relative
to the drive's range), simulated through the base model on the record's own drives, must
stay detectable after what the base model would absorb. A two-level drive cannot show it —
the operator of a two-level signal is a gain change, all absorbed — so the diagnosis asks for
multi-level excitation. (Recorded drives of a closed valve loop can overshoot after each
switch of a binary reference: the operator then sees reversals and the loop may show.)
"""

from __future__ import annotations

import math

import numba
import numpy as np

from rigd.effects import detectability as DT
from rigd.effects import numbers as N
from rigd.effects._drive import drive_note, drive_spread, valve_pairs
from rigd.effects._signals import n_levels
from rigd.effects.base import Effect, dims
from rigd.effects.context import CannotReveal, Context
from rigd.effects.signature import SignatureFit, signature_fit

#: Bouc–Wen rates c tried by the signature, per half-amplitude of the drive
#: (:func:`drive_spread`; c = GRID / spread in 1/V): relative to the record's scale, so the
#: same record in other units gives the same operator; the refit starts from the best
GRID = (0.25, 0.5, 1.0, 2.0, 4.0)
#: bounds of c, per half-amplitude of the drive
C_BOUNDS = (0.02, 50.0)
#: nominal loop for "can the record tell": half-width as a share of the input's range (a full
#: width of 10 % of the stroke, typical of piezo stacks),
#: operator rates as reversals' saturation within 1/g of the drive's range
NOMINAL_SHARE = 0.05
NOMINAL_G = (2.0, 8.0, 32.0)


@numba.njit(cache=True)
def bouc_wen(w: np.ndarray, c: float) -> np.ndarray:
    """Normalised Bouc–Wen operator (n = 1, β = γ) of ``w``, solved exactly per sample.

    The state h starts at 0; moving against h it changes linearly with slope c until it
    crosses zero, moving with h it approaches ±1 as 1 − (1 − |h|)·exp(−c·|Δw|).
    """
    n = w.shape[0]
    out = np.empty(n)
    h = 0.0
    out[0] = 0.0
    for k in range(1, n):
        dw = w[k] - w[k - 1]
        if dw != 0.0:
            sg = 1.0 if dw > 0.0 else -1.0
            a = abs(dw)
            hs = sg * h
            if hs < 0.0:
                need = -hs / c
                if a <= need:
                    h = h + sg * c * a
                    out[k] = h
                    continue
                a -= need
                hs = 0.0
            h = sg * (1.0 - (1.0 - hs) * math.exp(-c * a))
        out[k] = h
    return out


def operator_inputs(data, c: float) -> np.ndarray:
    """(n, nu): (φ_c(v_+) − φ_c(v_−))/2 per axis from the recorded drives, else φ_c(u)."""
    pairs = valve_pairs(data)
    u = np.asarray(data.inputs, float)
    if pairs is None:
        return np.stack([bouc_wen(np.ascontiguousarray(u[:, j]), c)
                         for j in range(u.shape[1])], axis=1)
    return np.stack([0.5 * (bouc_wen(p, c) - bouc_wen(m, c)) for p, m in pairs], axis=1)


class Hysteresis(Effect):
    name = "hysteresis"
    sites = ("input",)
    submodels = ("actuator", "generic")
    physics = "hysteresis (piezo valves): the response depends on the direction of motion"
    linear_note = ("rate-independent (Bouc–Wen on the valve drives): no small-signal "
                   "transfer function; its first-order part, a gain change, is in the "
                   "refitted base")

    def reveal(self, ctx: Context) -> CannotReveal | None:
        pairs = valve_pairs(ctx.data)
        w = np.asarray(pairs[0][0] if pairs is not None else ctx.u[:, 0], float)
        span = max(float(np.ptp(w)), 1e-300)
        amp = NOMINAL_SHARE * np.ptp(ctx.u, axis=0)
        sigs = []
        for g in NOMINAL_G:
            h = operator_inputs(ctx.data, g / span)
            sigs.append(sum(ctx.through_model(-amp[j] * h[:, j], j) for j in range(ctx.nu)))
        d, _ = DT.best(ctx, sigs, k=ctx.nu + 1)
        if d.detectable or (d.absorbed < 0.999 and DT.seen(ctx, self.signature(ctx))):
            return None
        lv = min(n_levels(ctx.u[:, j]) for j in range(ctx.nu))
        what = (f"the input has only {lv} levels: a hysteresis loop of half-width "
                f"{100 * NOMINAL_SHARE:.0f} % of the input range acts as a gain change"
                if lv <= 2 else f"a hysteresis loop of half-width {100 * NOMINAL_SHARE:.0f} % "
                "of the input range would not show on this input")
        why = f"{what} ({d.describe()})"  # the experiment: rigd.diagnose.advice
        return CannotReveal(self.name, why, "", ctx.submodel, code="few_levels",
                            evidence={"why": why})

    # --- signature ---------------------------------------------------------------------
    def _regs(self, ctx: Context, c: float) -> list[np.ndarray]:
        h = operator_inputs(ctx.data, c)
        return [ctx.through_model(-h[:, j], j) for j in range(ctx.nu)]

    def _signature(self, ctx: Context) -> SignatureFit:
        sc = drive_spread(ctx.data)
        best, best_c = None, GRID[0] / sc
        for c in (g / sc for g in GRID):
            s = signature_fit(ctx, self._regs(ctx, c))
            if best is None or s.score_est > best.score_est:
                best, best_c = s, c
        best.extra = {"c": best_c, "operator_input": drive_note(ctx.data)}
        return best

    def regressors(self, ctx):
        return self._regs(ctx, 1.0 / drive_spread(ctx.data))

    def explain(self, ctx, sig):
        du = np.gradient(ctx.u, axis=0)
        r = ctx.residual
        up, dn = du > 0, du < 0
        # direction of the last motion, held while the input holds still
        last = np.zeros_like(ctx.u)
        for j in range(ctx.nu):
            s = np.sign(np.diff(ctx.u[:, j], prepend=ctx.u[0, j]))
            idx = np.maximum.accumulate(np.where(s != 0, np.arange(s.size), 0))
            last[:, j] = s[idx]
        diffs = []
        for j in range(ctx.nu):
            i = j if j < ctx.ny else 0
            a, b = last[:, j] > 0, last[:, j] < 0
            diffs.append(float(np.mean(r[a, i]) - np.mean(r[b, i])) if a.any() and b.any()
                         else 0.0)
        j = int(np.argmax(np.abs(diffs)))
        ev = {"last_up_minus_last_down": {ctx.label(i, "in"): d for i, d in enumerate(diffs)},
              "rising_samples": int(up.sum()), "falling_samples": int(dn.sum())}
        ev.update(sig.extra)
        ev["site"] = "input"  # the restoring-force site: rigd.effects.restoring_hysteresis
        return (f"the residual on {ctx.label(j if j < ctx.ny else 0)} is {diffs[j]:+.3g} "
                f"higher after {ctx.label(j, 'in')} last rose than after it last fell, and "
                f"stays so while the input holds still: hysteresis at the input ("
                f"{'loops in the r–u plane, piezo valves' if N.is_rotor(ctx) else 'actuator'}"
                f"); a Bouc–Wen operator on "
                f"{sig.extra.get('operator_input', 'the input')} explains "
                f"{100 * sig.score:.0f} % of the residual", ev)

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        _, nu = dims(base)
        return [f"hyst_A_{j}" for j in range(nu)] + ["hyst_c"]

    def theta0_effect(self, base, data):
        _, nu = dims(base)
        return np.concatenate([np.zeros(nu), [1.0 / drive_spread(data)]])

    def param_bounds(self, base):
        _, nu = dims(base)
        return (np.concatenate([np.full(nu, -np.inf), [0.0]]),
                np.concatenate([np.full(nu, np.inf), [np.inf]]))

    def record_bounds(self, base, rec):
        lo, hi = self.param_bounds(base)  # c per half-amplitude of the drive
        sc = rec.drive_spread
        lo[-1], hi[-1] = C_BOUNDS[0] / sc, C_BOUNDS[1] / sc
        return lo, hi

    def warm_start(self, ctx, sig):
        c = sig.extra.get("c", 1.0 / drive_spread(ctx.data))
        return np.concatenate([np.asarray(sig.beta, float)[:ctx.nu], [c]])

    def input_block(self, u, theta_e, data):
        """u − A ∘ z(drives): the Bouc–Wen operator of the drives, per input."""
        nu = u.shape[1]
        te = np.asarray(theta_e, float)
        A, c = te[:nu], max(float(te[nu]), 1e-300)
        if not np.any(A):
            return u
        return u - A * operator_inputs(data, c)
