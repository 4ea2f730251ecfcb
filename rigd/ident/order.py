"""Generic models of the right order: the n-DOF mechanical base plus parallel modes.

A record from another rig may carry more modes than it has outputs (a flexible structure
measured at one point). :class:`ModalStructure` is the generic mechanical structure (one DOF
per output, :func:`rigd.ident.mechanical.generic_structure`) plus ``m`` parallel modes,
each ω²/(s² + 2ζω s + ω²) from every input to every output with its own gains
(``modeK_f_hz``, ``modeK_zeta``, ``modeK_g_<in>_<out>``). It is a structure like the others
(fitted by PEM or OE, the state-level effects' feedback into its mechanical part, model
files, ``ss``).

:func:`choose_order` picks the number of modes from the data:

1. fit the base (one mode per output) by output error on the estimation part;
2. repeat: a subspace estimate (:mod:`rigd.ident.lti.subspace`) of the dynamics left in
   the residual u → y − ŷ gives the candidate mode(s) away from the model's modes; their
   gains by linear least squares; the whole model refined by output error;
3. keep the mode when it raises the *validation* fit by at least ``MIN_GAIN`` points — the
   practical-significance rule of the diagnosis (``rigd.diagnose.engine.MIN_FIT_GAIN``) —
   and stop at the first mode that does not (or at ``max_modes``).

Frequencies are bounded relative to the record (two periods in the estimation part ..
0.95·Nyquist), damping to 0 < ζ < 1: nothing depends on the units or on the rate given.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.ident.feedback import MechanicalFeedback
from rigd.ident.figures import mean_fit
from rigd.ident.simulate import ExtraMode, parallel_modes
from rigd.ident.structure import Structure
from rigd.ident.thresholds import MIN_FIT_GAIN, MODE_SEPARATION

#: validation fit (points) a mode must add to be kept: the practical significance
MIN_GAIN = MIN_FIT_GAIN
#: most modes in all (base DOFs included) tried by ``order="auto"``
MAX_MODES = 6
#: relative distance from an existing mode for a candidate to count as new
MIN_SEPARATION = MODE_SEPARATION


class ModalStructure(Structure):
    """``base`` (a generic :class:`~rigd.ident.mechanical.MechanicalStructure`) plus ``m``
    parallel modes (see module docstring)."""

    #: the base's states are [p, ṗ] (state-level effects act on them; the parallel modes
    #: are added to the output)
    mechanical = True

    def __init__(self, base: Any, m: int):
        self.base = base
        self.m = int(m)
        self.kind = base.kind
        self.hold = base.hold
        self.nu, self.n = base.nu, base.n
        self.input_names, self.output_names = base.input_names, base.output_names
        self.nb = len(base.names)
        names = list(base.names)
        x0 = list(base.x0_index)
        for k in range(self.m):
            pre = f"mode{k + 2}_"
            names += [pre + "f_hz", pre + "zeta"]
            names += [f"{pre}g_{a}_{b}" for a in base.input_names for b in base.output_names]
            x0 += list(range(len(names), len(names) + 2 * self.n))
            names += [f"{pre}x0{c}_{b}" for c in "cs" for b in base.output_names]
        self.names = names
        # initial states: the base's and the free response of each parallel mode
        self.x0_index = x0
        self.offset_index = list(base.offset_index)
        self.effects = []
        self._per = 2 + self.nu * self.n + 2 * self.n
        self._fs: float | None = None

    @property
    def ny(self) -> int:
        return self.n

    # --- parameters ----------------------------------------------------------------
    def modes_of(self, theta) -> list[tuple[float, float, np.ndarray]]:
        """[(f_hz, zeta, g (nu, ny))] of the parallel modes."""
        th = np.asarray(theta, float)[self.nb:]
        out = []
        ng = self.nu * self.n
        for k in range(self.m):
            t = th[k * self._per:(k + 1) * self._per]
            out.append((float(t[0]), float(t[1]), t[2:2 + ng].reshape(self.nu, self.n)))
        return out

    def free_response(self, theta, n: int, fs: float) -> np.ndarray | None:
        """(n, ny) free response of the parallel modes from their initial states:
        e^(−ζωt)(a cos ω_d t + b sin ω_d t) per mode and output."""
        th = np.asarray(theta, float)[self.nb:]
        t = np.arange(n) / float(fs)
        out = None
        ng = self.nu * self.n
        for k in range(self.m):
            blk = th[k * self._per:(k + 1) * self._per]
            f, z = blk[0], min(max(blk[1], 0.0), 0.999)
            ab = blk[2 + ng:].reshape(2, self.n)
            if not np.any(ab):
                continue
            w = 2 * np.pi * f
            wd = w * np.sqrt(1 - z * z)
            env = np.exp(-z * w * t)
            y = (env * np.cos(wd * t))[:, None] * ab[0] + (env * np.sin(wd * t))[:, None] * ab[1]
            out = y if out is None else out + y
        return out

    def theta0(self, data) -> np.ndarray:
        tb = np.asarray(self.base.theta0(data), float)
        self._fs = float(data.fs)
        extra = []
        for k in range(self.m):  # spread over the band; choose_order gives better starts
            extra += ([float(data.fs) * 0.05 * (k + 2), 0.05] + [0.0] * (self.nu * self.n)
                      + [0.0] * (2 * self.n))
        return np.concatenate([tb, extra])

    def bounds(self):
        lo, hi = self.base.bounds()
        fmax = 0.95 * self._fs / 2 if self._fs else np.inf
        elo, ehi = [], []
        for _ in range(self.m):
            elo += [self._fmin, 1e-4] + [-np.inf] * (self.nu * self.n + 2 * self.n)
            ehi += [fmax, 0.95] + [np.inf] * (self.nu * self.n + 2 * self.n)
        return np.concatenate([lo, elo]), np.concatenate([hi, ehi])

    _fmin = 0.0

    def set_record(self, fs: float, n_est: int) -> None:
        """Bounds relative to the record: f in [2 periods per estimation part, 0.95 Nyquist]."""
        self._fs = float(fs)
        self._fmin = 2.0 * float(fs) / max(int(n_est), 1)

    def scale(self, theta):
        th = np.asarray(theta, float)
        sb = np.asarray(self.base.scale(th[:self.nb]), float)
        se = []
        ys = float(np.max(sb[self.base.x0_index[:self.n]]))  # output scale of the base
        for f, _z, g in self.modes_of(th):
            gs = max(float(np.max(np.abs(g))), 1e-300) if g.size else 1.0
            se += [max(abs(f), 1e-9), 0.05] + [gs] * g.size + [ys] * (2 * self.n)
        return np.concatenate([sb, se])

    # --- simulation --------------------------------------------------------------------
    def parallel_output(self, theta, data) -> np.ndarray | None:
        """(n, ny) output of the parallel modes driven by the inputs of ``data`` (the base's
        hold) plus their free response; None without either."""
        modes = []
        for f, z, g in self.modes_of(theta):
            w = 2 * np.pi * f
            for j in range(self.nu):
                b = np.zeros(self.nu)
                b[j] = w * w
                modes.append(ExtraMode(w, z, b, g[j].copy()))
        out = parallel_modes(modes, np.ascontiguousarray(data.u, dtype=float),
                             1.0 / float(data.fs), self.base.hold)
        free = self.free_response(theta, data.n, data.fs)
        if free is not None:
            out = free if out is None else out + free
        return out

    def simulate(self, theta, data, feedback: MechanicalFeedback | None = None):
        """The base's output (with the state-level effects' ``feedback``, rigd.ident.feedback)
        plus the parallel modes'."""
        th = np.asarray(theta, float)
        y = self.base.simulate(th[:self.nb], data, feedback)
        add = self.parallel_output(th, data)
        return y if add is None else y + add

    def predict(self, theta, data, feedback: MechanicalFeedback | None = None):
        """The base's one-step prediction of the measurement less the parallel modes'
        output, plus that output."""
        th = np.asarray(theta, float)
        add = self.parallel_output(th, data)
        d = data if add is None else dataclasses.replace(data, y=data.y - add)
        yh = self.base.predict(th[:self.nb], d, feedback)
        return yh if yh is None or add is None else yh + add

    def output_offset(self, theta):
        """The base's constant output offsets (None without them)."""
        return self.base.output_offset(np.asarray(theta, float)[:self.nb])

    def continuous(self, theta):
        """The base's (A, B, C, D, x0) (states [p, ṗ], for state-level effects)."""
        return self.base.continuous(np.asarray(theta, float)[:self.nb])

    def full_abcd(self, theta):
        """(A, B, C, D) of the whole linear model, parallel modes included."""
        A0, B0, C0, D0, _ = self.continuous(theta)
        blocks_A, blocks_B, blocks_C = [A0], [B0], [C0]
        for f, z, g in self.modes_of(theta):
            w = 2 * np.pi * f
            for j in range(self.nu):
                blocks_A.append(np.array([[0.0, 1.0], [-w * w, -2 * z * w]]))
                b = np.zeros((2, self.nu))
                b[1, j] = w * w
                blocks_B.append(b)
                c = np.zeros((self.n, 2))
                c[:, 0] = g[j]
                blocks_C.append(c)
        from scipy.linalg import block_diag

        return (block_diag(*blocks_A), np.vstack(blocks_B), np.hstack(blocks_C), D0)

    def linear_part(self, theta):
        """The whole linear model (parallel modes included) as a LinearPart."""
        from rigd.ident.model import LinearPart

        A, B, C, D = self.full_abcd(theta)
        return LinearPart(A, B, C, D, None, (0,) * self.nu, self.hold,
                          tuple(self.input_names), tuple(self.output_names))

    def ss(self, theta):
        import control

        A, B, C, D = self.full_abcd(theta)
        return control.ss(A, B, C, D, inputs=self.input_names, outputs=self.output_names,
                          name=self.kind)

    def resonances_hz(self, theta) -> list[float]:
        """Natural frequencies (Hz) of every mode, base and parallel."""
        lam = np.linalg.eigvals(self.full_abcd(theta)[0])
        return sorted({round(float(abs(v) / (2 * np.pi)), 6) for v in lam if v.imag > 1e-9})

    def readouts(self, theta):
        """Read-outs of the whole model (parallel modes included: rigd.ident.readouts)."""
        from rigd.ident.readouts import linear_readouts

        out = linear_readouts(self.linear_part(theta))
        off = self.output_offset(theta)
        if off is not None:
            out["output_offset"] = off.tolist()
        return out

    def spec(self):
        d = dict(self.base.spec())
        d["extra_modes"] = self.m
        return d


# --------------------------------------------------------------------------------------
# order selection
# --------------------------------------------------------------------------------------
@dataclass
class OrderChoice:
    """The chosen structure, its parameters and the validation fit of each order tried."""

    structure: Any
    theta: np.ndarray
    modes: int
    fits: dict[int, float] = field(default_factory=dict)
    reason: str = ""
    #: ``--order`` as asked (a number of states, 2 per mode, or ``auto``)
    asked: str | int = "auto"
    #: per-input delays (samples): the mechanical model has none
    delays: list[int] = field(default_factory=list)
    family: str = "mechanical"

    @property
    def states(self) -> int:
        """States of the model: 2 per mode (x = [p, ṗ] and each parallel mode's pair)."""
        return 2 * int(self.modes)

    def describe(self) -> str:
        tried = ", ".join(f"{k}: {v:.2f} %" for k, v in sorted(self.fits.items()))
        return (f"mechanical n-DOF model, {self.states} states ({self.modes} mode(s); "
                f"validation fit by number of modes: {tried}; {self.reason})")

    def to_json(self) -> dict[str, Any]:
        return {"modes": self.modes, "family": self.family, "states": self.states,
                "delays_samples": list(self.delays), "asked": self.asked,
                "validation_fit_by_modes":
                {str(k): round(v, 3) for k, v in sorted(self.fits.items())},
                "reason": self.reason}


def _fit_pct(y, yh):
    return mean_fit(y, yh)


def candidate_mode(u, r, fs, exclude_hz, hold="foh"):
    """(f_hz, zeta, g (nu, ny)) of the mode that explains most of the residual ``r`` (n, ny)
    given the inputs ``u`` (n, nu): subspace estimates of orders 2..6 of u → r, modes away
    from ``exclude_hz``, gains by least squares; None when none is found."""
    from rigd.ident.lti.subspace import continuous_modes, dynamics_matrices
    from rigd.lti import resonator

    cands = []
    # one decomposition per distinct horizon, A alone (the gains come below)
    tries = [(order, hz) for order in (2, 4, 6) for hz in (None, 4 * order + 10)]
    for A in dynamics_matrices(u, r, tries):
        if A is None:
            continue
        for f, z in continuous_modes(A, fs):
            if all(abs(f - e) > MIN_SEPARATION * e for e in exclude_hz):
                cands.append((f, z))
    best, best_ss = None, 0.0
    r0 = r - r.mean(0)
    tot = float(np.sum(r0 ** 2))
    for f, z in cands:
        regs = np.column_stack([resonator(u[:, j] - u[:, j].mean(), f, z, fs)[0]
                                for j in range(u.shape[1])])
        g, *_ = np.linalg.lstsq(regs, r0, rcond=None)
        ss = tot - float(np.sum((r0 - regs @ g) ** 2))
        if ss > best_ss:
            best, best_ss = (f, z, g), ss
    return best


def _unresolved(st: ModalStructure, theta) -> str:
    """'' when every pair of modes is resolvable, else which pair is not: closer than
    ``MIN_SEPARATION`` (relative) or with overlapping half-power bands (|f_i − f_j| ≤
    ζ_i f_i + ζ_j f_j)."""
    lam = np.linalg.eigvals(st.full_abcd(theta)[0])
    modes = sorted((abs(v) / (2 * np.pi), -v.real / abs(v)) for v in lam if v.imag > 1e-9)
    for (f1, z1), (f2, z2) in zip(modes, modes[1:]):
        if f2 - f1 < MIN_SEPARATION * f2 or f2 - f1 <= z1 * f1 + z2 * f2:
            return f"the modes at {f1:.4g} Hz and {f2:.4g} Hz overlap"
    return ""


def choose_order(base, data, est: slice, val: slice, order: str | int = "auto",
                 base_theta: np.ndarray | None = None, max_nfev: int | None = None,
                 max_modes: int = MAX_MODES) -> OrderChoice:
    """Base structure with the number of modes chosen from the data (module docstring).

    Parameters
    ----------
    base : MechanicalStructure
        Generic base (one DOF per output).
    data : IdData
        The whole (prefiltered) record; ``est``/``val`` the estimation/validation parts.
    order : "auto" or int
        ``auto``, or the number of modes (≥ the number of outputs) to fit.
    base_theta : ndarray, optional
        The base already fitted on the estimation part (skips that fit).
    """
    from rigd.ident.pem import fit

    d_est = data.slice(est.start, est.stop)
    yv = data.y[val]
    if base_theta is None:
        base_theta = fit(base, d_est, method="oe", max_nfev=max_nfev).theta
    st, th = base, np.asarray(base_theta, float)
    fits = {base.n: _fit_pct(yv, np.asarray(base.simulate(th, data))[val])}
    want = None if order == "auto" else int(order)
    if want is not None and want < base.n:
        raise ValueError(f"order {want} is below the {base.n} mode(s) of the base structure "
                         f"(one per output)")
    top = want if want is not None else max_modes
    reason = "no further mode found in the residual"
    fs = float(data.fs)
    for m in range(1, top - base.n + 1):
        yh_est = np.asarray(st.simulate(th, d_est))
        r = d_est.y - yh_est
        have = (st.resonances_hz(th) if isinstance(st, ModalStructure)
                else [md["f_n_hz"] for md in base.modes(th) if "f_n_hz" in md])
        cand = candidate_mode(d_est.u, r, fs, have, base.hold)
        if cand is None:
            reason = "no further mode found in the residual"
            break
        f, z, g = cand
        new = ModalStructure(base, m)
        new.set_record(fs, d_est.n)
        th0 = np.concatenate([th, [f, z], np.asarray(g, float).ravel(), np.zeros(2 * base.n)])
        lo, hi = new.bounds()
        th0 = np.clip(th0, lo, hi)
        try:
            res = fit(new, d_est, method="oe", theta0=th0, max_nfev=max_nfev)
        except (np.linalg.LinAlgError, ValueError):
            reason = "refit with one more mode failed"
            break
        yh = np.asarray(new.simulate(res.theta, data))
        if not np.all(np.isfinite(yh)):
            reason = "the model with one more mode is unstable"
            break
        fv = _fit_pct(yv, yh[val])
        fits[base.n + m] = fv
        clash = _unresolved(new, res.theta)
        if clash:
            reason = (f"one more mode is not a separate mode: after the refit {clash} "
                      "(what it fits is not a structural mode)")
            break
        if want is None and fv - fits[base.n + m - 1] < MIN_GAIN:
            reason = (f"one more mode adds {fv - fits[base.n + m - 1]:.2f} points "
                      f"(< {MIN_GAIN})")
            break
        st, th = new, res.theta
    else:
        reason = (f"order {want} asked" if want is not None else
                  f"the most modes tried ({max_modes})")
    modes = base.n + (st.m if isinstance(st, ModalStructure) else 0)
    return OrderChoice(st, th, modes, fits, reason)
