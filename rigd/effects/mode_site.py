"""Effects at the ``mode`` site: a restoring force on one mode of a measured modal model.

A bolted joint, a clearance or a stiffening spring in the load path of one mode of a
structure makes *that* mode nonlinear — as structural dynamicists model a joint (a nonlinear
mode): q̈ + 2ζω q̇ + ω² q + φ(q, q̇) = b·u, with q the modal coordinate of one complex pair
of a general LTI base (:mod:`rigd.ident.lti.nonlinear_mode`). Each effect here names its
mode by a parameter ``<name>_mode`` (the pair's index in the base, 1-based, held in every
fit) and is worded by the mode's frequency ("a joint at the 7.8 Hz mode").

* ``joint`` — an Iwan element: :data:`N_SLIDERS` Jenkins elements (a spring in series with a
  Coulomb slider) with slip forces spread evenly up to ``joint_fslip`` (input unit) over a
  share ``joint_spread`` of it (0: one Jenkins element, 1: from zero). The base's
  mode is the joint stuck; as the sliders slip the mode softens by up to ``joint_share`` of
  its stiffness and the hysteresis loops dissipate: stiffness and damping that depend on
  amplitude.
* ``clearance`` — a dead-zone spring: ``clearance_share`` · ω² beyond a gap whose force in the
  mode's linear spring is ``clearance_gapf`` (input unit): the mode stiffens with amplitude.
* ``mode_cubic`` — a stiffening cubic spring on the mode: φ = c3 ω² q (ω² q)², c3 ≥ 0
  (``mode_cubic_c3`` per input unit squared; a softening cubic loses the stiffness at a finite
  amplitude, a softening that levels off is the joint's).

Which mode: the signature of each law — the output change of its forces fed into the mode
(first order) and of the law itself at a few plausible sizes — is regressed, mode by mode,
for every lightly damped pair where the input has power; the mode whose regressors explain
the most of the estimation residual is the one the effect is refitted at
(:meth:`ModeEffect.choose_mode`), from the two sizes that explained most. The law's force
also has a direct share in each output (``<name>_d<i>``): an accelerometer sees the mode's
q̈, so the force at once. Every effect requires ``mode`` (a base with modal blocks,
``rigd.effects.compose.carries``); one mode effect per model.
"""

from __future__ import annotations

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
    excited = excited_by(data, est)
    out = []
    for k in range(1, int(base.nc) + 1):
        fk, zk = NM.mode_hz(base, theta_b, k)
        if excited(fk, zk):
            out.append(k)
    return out


def excited_by(data, est: slice | None = None):
    """``excited(f_hz, zeta) -> bool``: is a mode at ``f_hz`` of damping ratio ``zeta`` one
    the input of ``data`` (its ``est`` part) excites — ζ < :data:`MAX_ZETA` and the input
    PSD there ≥ :data:`IN_BAND` of its peak (Welch, summed over the inputs)."""
    from scipy import signal as sg

    u = np.asarray(data.u, float)[est or slice(None)]
    f, p = sg.welch(u - u.mean(0), fs=float(data.fs), nperseg=min(len(u), 1024), axis=0)
    p = p.sum(axis=1)
    floor = IN_BAND * p.max()
    return lambda f_hz, zeta: bool(zeta < MAX_ZETA and np.interp(f_hz, f, p) >= floor)


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
    #: refitted whenever the signature shows (rigd.diagnose.selection.screen), not only on a
    #: decisive one: on a base that already fits well (98 %) a joint's first-order signature
    #: is small while its refit halves the error
    costly_refit = False
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

    def law_starts(self, w2: float, q_std: float) -> list[np.ndarray]:
        """Plausible sizes of the law on a mode of ω² = ``w2`` whose coordinate has the
        spread ``q_std``: the nonlinear signatures and the refit's starts."""
        raise NotImplementedError

    # --- mode choice ---------------------------------------------------------------------
    def mode_regressors(self, base, theta_b, data, k: int, est: slice) -> tuple[list, dict]:
        """First-order signature of the law on mode ``k``: the output change of each of
        :meth:`forces` fed into the mode; and the mode's ``info`` (NM.mode_force)."""
        info = NM.mode_force(base, theta_b, data, k)
        q, v = info["q"], info["v"]
        qs, vs = max(q[est].std(), 1e-300), max(v[est].std(), 1e-300)
        info["q_std"] = qs
        fs = float(data.fs)
        return [NM.force_response(info, f, fs) for f in self.forces(q / qs, v / vs)], info

    def scan(self, structure, theta, data, residual, est: slice) -> dict[int, dict]:
        """Per excited mode (:func:`in_band_modes`): the first-order regressors plus the
        output change of the law at the size of :meth:`law_starts` that explains most of
        the ``residual`` on ``est`` (a strong joint's first-order signature is poor: the
        base's mode is a compromise of amplitudes); ``score`` the in-sample share of all
        of them (every mode has as many regressors, so the shares compare; held out, a long
        modal transient at the record's start can flip them), ``starts`` the sizes ranked."""
        base, tb = _base_theta(structure, theta)
        ext = self.extend(base)
        y0 = np.asarray(base.simulate(tb, data), float)
        out = {}
        for k in in_band_modes(base, tb, data, est):
            try:
                regs, info = self.mode_regressors(base, tb, data, k, est)
            except ValueError:
                continue
            cands = []
            d0 = self.direct_start(base, info)
            for p in self.law_starts(info["w2"], info["q_std"]):
                p = np.r_[p, d0]
                try:
                    dy = np.asarray(ext.simulate(np.r_[tb, float(k), p], data), float) - y0
                except (ValueError, FloatingPointError):
                    continue
                if np.all(np.isfinite(dy)) and np.any(dy):
                    cands.append((_share([dy], residual, est, est), p, dy))
            cands.sort(key=lambda c: -c[0])
            full = regs + [cands[0][2]] if cands else regs
            out[k] = {"score": _share(full, residual, est, est), "regs": full, "info": info,
                      "starts": [c[1] for c in cands]}
        return out

    def choose_mode(self, structure, theta, data, residual, est: slice
                    ) -> tuple[int, dict[int, dict]]:
        """(the mode of the highest :meth:`scan` score, the scan); (0, {}) when the base
        excites no mode."""
        sc = self.scan(structure, theta, data, residual, est)
        if not sc:
            return 0, {}
        return max(sc, key=lambda k: sc[k]["score"]), sc

    def _signature(self, ctx):
        k, sc = self.choose_mode(ctx.structure, ctx.theta, ctx.data, ctx.residual, ctx.est)
        ctx.cache[("mode", self.name)] = (k, sc)
        return signature_fit(ctx, sc[k]["regs"] if k else [])

    def refit_starts(self, ctx, sig) -> list[np.ndarray | None]:
        """The two sizes of the law that explained most of the residual, at the chosen
        mode (the refit keeps the lower estimation cost)."""
        k, sc = ctx.cache.get(("mode", self.name), (0, {}))
        if not k or not sc[k]["starts"]:
            return [None]
        return [np.r_[float(k), p] for p in sc[k]["starts"][:2]]

    def warm_start(self, ctx, sig):
        return self.refit_starts(ctx, sig)[0]

    def start_on(self, structure, theta, data) -> np.ndarray | None:
        """Start values on the fitted ``structure`` (``rigd identify --add``): the mode and
        size by :meth:`choose_mode` on ``data``."""
        y = np.asarray(data.y, float)
        r = y - np.asarray(structure.simulate(theta, data), float)
        k, sc = self.choose_mode(structure, theta, data, r, slice(0, len(y)))
        if not k or not sc[k]["starts"]:
            return None
        return np.r_[float(k), sc[k]["starts"][0]]

    def explain(self, ctx, sig):
        k, sc = ctx.cache.get(("mode", self.name), (0, {}))
        scores = {m: v["score"] for m, v in sc.items()}
        if not k:
            return f"{self.physics}: the input excites no mode of the model", {"site": "mode"}
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
        """The mode, the law's parameters, the force's direct share of each output
        (``<name>_d<i>``: a sensor of the mode's acceleration sees it at once)."""
        ny = self._ny(base)
        return ([f"{self.name}_mode"] + [f"{self.name}_{n}" for n in self.law_names()]
                + [f"{self.name}_d{i + 1}" for i in range(ny)])

    def _ny(self, base) -> int:
        return int(base_of(base).ny)

    def direct_start(self, base, info) -> np.ndarray:
        """The direct share of each output at the start: with a feedthrough in the base
        (sensors of acceleration) the output row on [q, q̇] is c·(−ω² q − 2ζω q̇) and the
        share c = −(row on q)/ω²; without one, 0."""
        if not base_of(base).feedthrough:
            return np.zeros(self._ny(base))
        return -np.asarray(info["Cq"][:, 0], float) / info["w2"]

    def fixed_names(self, base):
        return [f"{self.name}_mode"]

    def theta0_effect(self, base, data):
        """Mode 1, the law's start for a unit mode (the refit's and ``--add``'s starts are
        :meth:`warm_start` / :meth:`start_on`, on the fitted base)."""
        return np.r_[1.0, self.law_starts(1.0, 1.0)[0], np.zeros(self._ny(base))]

    def param_bounds(self, base):
        """The mode's index within [0.5, pairs + 0.5] (an index, held: never at a bound),
        the law's own bounds."""
        nc = max(int(base_of(base).nc), 1)
        lo, hi = self.law_bounds(None)
        ny = self._ny(base)
        return (np.array([0.5] + lo + [-np.inf] * ny),
                np.array([nc + 0.5] + hi + [np.inf] * ny))

    def record_bounds(self, base, rec):
        nc = max(int(base_of(base).nc), 1)
        lo, hi = self.law_bounds(float(np.max(rec.u_spread)))
        ny = self._ny(base)
        return (np.array([0.5] + lo + [-np.inf] * ny),
                np.array([nc + 0.5] + hi + [np.inf] * ny))

    def param_typical(self, base, rec):
        """1 for the mode, the law's (:meth:`law_typical`), output per input spread for
        the direct shares."""
        ny = self._ny(base)
        d = np.asarray(rec.y_spread, float)[:ny] / max(float(np.max(rec.u_spread)), 1e-300)
        return np.r_[1.0, self.law_typical(rec), np.broadcast_to(d, (ny,))]

    def law_bounds(self, spread: float | None) -> tuple[list[float], list[float]]:
        raise NotImplementedError

    def owns_state(self, base):
        return True

    def sensitivities(self, base, theta_b, theta_e, data, idx, dY):
        """Exact columns of the model with the law on its mode, from the base's ``(idx,
        dY)`` on ``data``. The output is the base's plus ``(x_k − x_k^lin) C_kᵀ − φ·d``
        (:func:`rigd.ident.lti.nonlinear_mode.simulate_nonlinear_mode`), a term of the
        mode's block alone: every other base column is the base's; a column of ``C_k``
        is the base's plus the departure of its state; a direct share's is −φ. The mode's
        pole, its rows of B and its x0 move the law's response: none is returned."""
        te = np.asarray(theta_e, float)
        k = int(round(te[0]))
        s = NM.mode_states(base, k)
        w2 = float(abs(np.linalg.det(base.matrices(theta_b)["A"][s:s + 2, s:s + 2])))
        nl = len(self.law_names())
        p, nel, extra = self.law_params(te[1:1 + nl], w2)
        dx, fn, _ = NM.mode_departure(base, theta_b, data, k, self.law, p, nel, extra)
        pair = sum(1 for t, q in base.block_states() if t == "pair" and q < s)
        moved = {f"p{pair + 1}_lnf", f"p{pair + 1}_zeta"}
        moved |= {f"b{q + 1}_{j + 1}" for q in (s, s + 1) for j in range(base.nu)}
        moved |= {f"x0_{q + 1}" for q in (s, s + 1)}
        c_cols = {f"c{i + 1}_{q + 1}": (i, q - s) for q in (s, s + 1) for i in range(base.ny)}
        keep, cols = [], []
        for r, par in enumerate(np.asarray(idx, int)):
            name = base.names[par]
            if name in moved:
                continue
            col = dY[r]
            if name in c_cols:
                i, j = c_cols[name]
                col = col.copy()
                col[:, i] += dx[:, j]
            keep.append(par)
            cols.append(col)
        own = list(range(1 + nl, 1 + nl + base.ny))
        for i in range(base.ny):
            col = np.zeros((fn.size, base.ny))
            col[:, i] = -fn
            cols.append(col)
        return np.asarray(keep, int), np.asarray(own, int), np.stack(cols)

    def state_simulate(self, base, theta_b, theta_e, fb, data):
        """Output (n, ny) of ``base`` with the law on the mode ``theta_e[0]``."""
        if fb is not None:
            raise ValueError(f"{self.name} acts on a mode; state feedback cannot be beside it")
        te = np.asarray(theta_e, float)
        k = int(round(te[0]))
        s = NM.mode_states(base, k)
        w2 = float(abs(np.linalg.det(base.matrices(theta_b)["A"][s:s + 2, s:s + 2])))
        nl = len(self.law_names())
        p, nel, extra = self.law_params(te[1:1 + nl], w2)
        return NM.simulate_nonlinear_mode(base, theta_b, data, k, self.law, p, nel, extra,
                                          te[1 + nl:])


class Joint(ModeEffect):
    name = "joint"
    law = "iwan"
    word = "joint"
    physics = ("a bolted joint (Iwan: springs with slipping friction): the mode softens and "
               "its damping rises with amplitude")

    def law_names(self):
        return ["share", "fslip", "spread"]

    def forces(self, q, v):
        return [q * np.abs(q), v * np.abs(q)]

    def law_params(self, te, w2):
        """Element e of :data:`N_SLIDERS` slips at fslip·(1 − spread·(N − 1 − e)/N): all
        at fslip (spread 0, a Jenkins element), evenly from fslip/N (spread 1)."""
        share, fslip = float(te[0]), max(float(te[1]), 1e-300)
        spread = float(np.clip(te[2], 0.0, 1.0))
        ke = share * w2 / N_SLIDERS
        e = np.arange(N_SLIDERS)
        slip = fslip * (1.0 - spread * (N_SLIDERS - 1 - e) / N_SLIDERS)
        return np.concatenate([[ke], slip]), N_SLIDERS, 0.0

    def law_starts(self, w2, q_std):
        """A tenth and a third of the stiffness in the joint, the sliders slipping from
        one and from three spreads of the coordinate, their slip forces spread evenly from
        zero or within a fifth of the largest."""
        return [np.array([sh, sh * w2 * a * q_std, sp]) for sh in (0.1, 0.3)
                for a in (1.0, 3.0) for sp in (1.0, 0.2)]

    def law_bounds(self, spread):
        s = 1.0 if spread is None else spread
        return [0.0, 1e-6 * s, 0.0], [0.9, 1e4 * s, 1.0]

    def law_typical(self, rec):
        return np.array([0.1, float(np.max(rec.u_spread)), 0.1])


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

    def law_starts(self, w2, q_std):
        """A tenth and a half of the stiffness beyond gaps of a half and one and a half
        spreads of the coordinate."""
        return [np.array([sh, w2 * a * q_std]) for sh in (0.1, 0.5) for a in (0.5, 1.5)]

    def law_bounds(self, spread):
        s = 1.0 if spread is None else spread
        return [0.0, 0.0], [3.0, 1e4 * s]

    def law_typical(self, rec):
        return np.array([0.05, float(np.max(rec.u_spread))])


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

    def law_starts(self, w2, q_std):
        """Stiffening by a tenth and by a half of the linear force at two spreads."""
        return [np.array([c / (2.0 * w2 * q_std) ** 2]) for c in (0.1, 0.5)]

    def law_bounds(self, spread):
        """Stiffening only: a softening cubic loses the mode's stiffness at a finite
        amplitude (the model diverges beyond it); a softening that levels off is a joint."""
        return [0.0], [np.inf]

    def law_typical(self, rec):
        return np.array([1.0 / max(float(np.max(rec.u_spread)), 1e-300) ** 2])


def mode_effects() -> list[ModeEffect]:
    """One instance of each mode-site effect (for the registry)."""
    return [Joint(), Clearance(), ModeCubic()]
