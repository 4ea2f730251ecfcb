"""Effects at the ``mode`` site: a restoring force on one mode of a measured modal model.

A bolted joint, a clearance or a stiffening spring in the load path of one mode of a
structure makes *that* mode nonlinear — as structural dynamicists model a joint (a nonlinear
mode): q̈ + 2ζω q̇ + ω² q + φ(q, q̇) = b·u, with q the modal coordinate of one complex pair
of a general LTI base (:mod:`rigd.ident.lti.nonlinear_mode`). Each effect here names its
mode by a parameter ``<name>_mode`` (the pair's index in the base, 1-based, held in every
fit) and is worded by the mode's frequency ("a joint at the 7.8 Hz mode").

* ``joint`` — an Iwan element: :data:`N_SLIDERS` Jenkins elements (a spring in series with a
  Coulomb slider) with slip forces spread evenly up to ``joint_fslip`` (input unit). The base's
  mode is the joint stuck; as the sliders slip the mode softens by up to ``joint_share`` of
  its stiffness and the hysteresis loops dissipate: stiffness and damping that depend on
  amplitude.
* ``clearance`` — a dead-zone spring: ``clearance_share`` · ω² beyond a gap whose force in the
  mode's linear spring is ``clearance_gapf`` (input unit): the mode stiffens with amplitude.
* ``mode_cubic`` — a cubic stiffness on the mode: φ = c3 ω² q (ω² q)² (``mode_cubic_c3`` per
  input unit squared).

Which mode: the signature of each law is regressed, mode by mode, for every lightly damped
pair where the input has power; the mode whose regressors explain the most of the held-out
residual is the one the effect is refitted at (:func:`choose_mode`). Every effect requires
``mode`` (a base with modal blocks, ``rigd.effects.compose.carries``); one mode effect per
model.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.effects import numbers as N
from rigd.effects.base import STRUCTURAL, Effect
from rigd.effects.signature import signature_fit
from rigd.ident.lti import nonlinear_mode as NM
from rigd.ident.model import base_of

#: Jenkins elements of the ``joint`` (an Iwan element of evenly spread slip forces)
N_SLIDERS = 4
#: a pair is a mode to screen when its damping ratio is below this and the input's power
#: at its frequency is at least :data:`IN_BAND` of the input's peak (Welch PSD)
MAX_ZETA, IN_BAND = 0.3, 1e-2
MODE_EFFECTS = ("joint", "clearance", "mode_cubic")


def in_band_modes(base, theta_b, data, est: slice | None = None) -> list[int]:
    """The pairs (1-based) of ``base`` at ``theta_b`` that are modes the input of ``data``
    excites: damping ratio < :data:`MAX_ZETA`, input PSD there ≥ :data:`IN_BAND` of its
    peak."""
    from scipy import signal as sg

    u = np.asarray(data.u, float)[est or slice(None)]
    f, p = sg.welch(u - u.mean(0), fs=float(data.fs), nperseg=min(len(u), 1024), axis=0)
    p = p.sum(axis=1)
    out = []
    for k in range(1, int(base.nc) + 1):
        fk, zk = NM.mode_hz(base, theta_b, k)
        if zk < MAX_ZETA and np.interp(fk, f, p) >= IN_BAND * p.max():
            out.append(k)
    return out


def _base_theta(structure, theta):
    base = base_of(structure)
    return base, np.asarray(theta, float)[:len(base.names)]


def _share(regs: list[np.ndarray], r: np.ndarray, est: slice, val: slice) -> float:
    """Share of the residual ``r`` energy on ``val`` the regressors explain (β on
    ``est``)."""
    w = 1.0 / np.maximum(r[est].std(axis=0), 1e-300)
    M = np.stack([g * w for g in regs], axis=-1)
    rw = r * w
    beta = np.linalg.lstsq(M[est].reshape(-1, M.shape[-1]), rw[est].ravel(), rcond=None)[0]
    e0 = float(np.sum(rw[val] ** 2))
    e1 = float(np.sum((rw[val] - M[val] @ beta) ** 2))
    return 1.0 - e1 / e0 if e0 > 0 else 0.0


class ModeEffect(Effect):
    """A restoring force φ(q) on one mode's coordinate (module docstring)."""

    sites = ("mode",)
    requires = ("mode",)
    domains = STRUCTURAL
    submodels = ("bearing", "generic")
    law = "cubic"
    linear_note = ("amplitude-dependent: the base's mode is its small-amplitude (linear) "
                   "part")

    def clashes_with(self, other: Effect) -> bool:
        return other.name != self.name and other.name in MODE_EFFECTS

    # --- the law's forces and parameters (per subclass) ------------------------------
    def law_names(self) -> list[str]:
        raise NotImplementedError

    def forces(self, q: np.ndarray, v: np.ndarray) -> list[np.ndarray]:
        """Signature forces of the law from the normalised coordinate and velocity."""
        raise NotImplementedError

    def law_params(self, te: np.ndarray, w2: float) -> tuple[np.ndarray, int, float]:
        """(kernel parameters, sliders, added stiffness rad²/s²) from the effect's own."""
        raise NotImplementedError

    def law_start(self, w2: float, q_std: float, beta: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    # --- mode choice ---------------------------------------------------------------------
    def mode_regressors(self, base, theta_b, data, k: int, est: slice) -> tuple[list, dict]:
        info = NM.mode_force(base, theta_b, data, k)
        q, v = info["q"], info["v"]
        qs, vs = max(q[est].std(), 1e-300), max(v[est].std(), 1e-300)
        info["q_std"] = qs
        fs = float(data.fs)
        return [NM.force_response(info, f, fs) for f in self.forces(q / qs, v / vs)], info

    def choose_mode(self, structure, theta, data, residual, est: slice
                    ) -> tuple[int, dict[int, float]]:
        """(the mode whose regressors explain most of the ``residual`` on ``est``, {mode:
        share}): every mode has as many regressors, so the in-sample shares compare
        (held out, a long modal transient at the record's start can flip them); (0, {})
        when the base excites none."""
        base, tb = _base_theta(structure, theta)
        scores = {}
        for k in in_band_modes(base, tb, data, est):
            try:
                regs, _ = self.mode_regressors(base, tb, data, k, est)
            except ValueError:
                continue
            scores[k] = _share(regs, residual, est, est)
        if not scores:
            return 0, {}
        return max(scores, key=scores.get), scores

    def _signature(self, ctx):
        k, scores = self.choose_mode(ctx.structure, ctx.theta, ctx.data, ctx.residual,
                                     ctx.est)
        ctx.cache[("mode", self.name)] = (k, scores)
        if not k:
            return signature_fit(ctx, [])
        base, tb = _base_theta(ctx.structure, ctx.theta)
        regs, info = self.mode_regressors(base, tb, ctx.data, k, ctx.est)
        ctx.cache[("mode_info", self.name)] = info
        return signature_fit(ctx, regs)

    def warm_start(self, ctx, sig):
        k, _ = ctx.cache.get(("mode", self.name), (0, {}))
        info = ctx.cache.get(("mode_info", self.name))
        if not k or info is None:
            return None
        return np.concatenate([[float(k)], self.law_start(info["w2"], info["q_std"],
                                                          np.asarray(sig.beta, float))])

    def start_on(self, structure, theta, data) -> np.ndarray | None:
        """Start values on the fitted ``structure`` (``rigd identify --add``): the mode by
        :meth:`choose_mode` on ``data``."""
        y = np.asarray(data.y, float)
        r = y - np.asarray(structure.simulate(theta, data), float)
        k, _ = self.choose_mode(structure, theta, data, r, slice(0, len(y)))
        if not k:
            return None
        base, tb = _base_theta(structure, theta)
        _, info = self.mode_regressors(base, tb, data, k, slice(0, len(y)))
        return np.concatenate([[float(k)], self.law_start(info["w2"], info["q_std"],
                                                          np.zeros(0))])

    def explain(self, ctx, sig):
        k, scores = ctx.cache.get(("mode", self.name), (0, {}))
        if not k:
            return f"{self.physics}: the input excites no mode of the model", {}
        base, tb = _base_theta(ctx.structure, ctx.theta)
        f, z = NM.mode_hz(base, tb, k)
        ev = {"site": "mode", "mode": int(k), "mode_hz": float(f), "mode_zeta": float(z),
              "mode_shares": {str(m): round(float(s), 4) for m, s in scores.items()}}
        return (f"a {self.word} at the {f:.3g} Hz mode: {self.physics}; its signature there "
                f"explains {N.share(sig.score)} of the residual (best of "
                f"{len(scores)} excited mode(s))", ev)

    word = "restoring force"

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        return [f"{self.name}_mode"] + [f"{self.name}_{n}" for n in self.law_names()]

    def fixed_names(self, base):
        return [f"{self.name}_mode"]

    def theta0_effect(self, base, data):
        """Mode 1, the law's start for a unit mode (the refit's and ``--add``'s starts are
        :meth:`warm_start` / :meth:`start_on`, on the fitted base)."""
        return np.concatenate([[1.0], self.law_start(1.0, 1.0, np.zeros(0))])

    def param_bounds(self, base):
        """The mode's index within [0.5, pairs + 0.5] (an index, held: never at a bound),
        the law's own bounds."""
        nc = max(int(getattr(base_of(base), "nc", 1) or 1), 1)
        lo, hi = self.law_bounds(None)
        return np.array([0.5] + lo), np.array([nc + 0.5] + hi)

    def record_bounds(self, base, rec):
        nc = max(int(getattr(base_of(base), "nc", 1) or 1), 1)
        lo, hi = self.law_bounds(float(np.max(rec.u_spread)))
        return np.array([0.5] + lo), np.array([nc + 0.5] + hi)

    def law_bounds(self, spread: float | None) -> tuple[list[float], list[float]]:
        raise NotImplementedError

    def owns_state(self, base):
        return True

    def state_simulate(self, base, theta_b, theta_e, fb, data):
        """Output (n, ny) of ``base`` with the law on the mode ``theta_e[0]``."""
        if fb is not None:
            raise ValueError(f"{self.name} acts on a mode; state feedback cannot be beside it")
        te = np.asarray(theta_e, float)
        k = int(round(te[0]))
        s = NM.mode_states(base, k)
        w2 = float(abs(np.linalg.det(base.matrices(theta_b)["A"][s:s + 2, s:s + 2])))
        p, nel, extra = self.law_params(te[1:], w2)
        return NM.simulate_nonlinear_mode(base, theta_b, data, k, self.law, p, nel, extra)


class Joint(ModeEffect):
    name = "joint"
    law = "iwan"
    word = "joint"
    physics = ("a bolted joint (Iwan: springs with slipping friction): the mode softens and "
               "its damping rises with amplitude")

    def law_names(self):
        return ["share", "fslip"]

    def forces(self, q, v):
        return [q * np.abs(q), v * np.abs(q)]

    def law_params(self, te, w2):
        share, fslip = float(te[0]), max(float(te[1]), 1e-300)
        ke = share * w2 / N_SLIDERS
        slip = fslip * np.arange(1, N_SLIDERS + 1) / N_SLIDERS
        return np.concatenate([[ke], slip]), N_SLIDERS, 0.0

    def law_start(self, w2, q_std, beta):
        share = 0.1
        return np.array([share, share * w2 * 2.0 * q_std])

    def law_bounds(self, spread):
        s = 1.0 if spread is None else spread
        return [0.0, 1e-6 * s], [0.9, 1e4 * s]

    def param_typical(self, base, rec):
        return np.array([1.0, 0.1, float(np.max(rec.u_spread))])


class Clearance(ModeEffect):
    name = "clearance"
    law = "clearance"
    word = "clearance"
    physics = "a clearance (a spring beyond a gap): the mode stiffens with amplitude"

    def law_names(self):
        return ["share", "gapf"]

    def forces(self, q, v):
        return [q * np.abs(q), q ** 3]

    def law_params(self, te, w2):
        kc = float(te[0]) * w2
        return np.array([kc, max(float(te[1]), 0.0) / w2]), 0, kc

    def law_start(self, w2, q_std, beta):
        return np.array([0.05, w2 * 1.5 * q_std])

    def law_bounds(self, spread):
        s = 1.0 if spread is None else spread
        return [0.0, 0.0], [3.0, 1e4 * s]

    def param_typical(self, base, rec):
        return np.array([1.0, 0.05, float(np.max(rec.u_spread))])


class ModeCubic(ModeEffect):
    name = "mode_cubic"
    law = "cubic"
    word = "cubic stiffness"
    physics = "a cubic stiffness (Duffing) on the mode"

    def law_names(self):
        return ["c3"]

    def forces(self, q, v):
        return [q ** 3]

    def law_params(self, te, w2):
        return np.array([float(te[0]) * w2 ** 3]), 0, 0.0

    def law_start(self, w2, q_std, beta):
        b = float(beta[0]) if beta.size else 0.0
        return np.array([b / (q_std ** 3 * w2 ** 3) if b else 1e-3 / (w2 * q_std) ** 2])

    def law_bounds(self, spread):
        return [-np.inf], [np.inf]

    def param_typical(self, base, rec):
        return np.array([1.0, 1.0 / max(float(np.max(rec.u_spread)), 1e-300) ** 2])


def mode_effects() -> list[ModeEffect]:
    """One instance of each mode-site effect (for the registry)."""
    return [Joint(), Clearance(), ModeCubic()]
