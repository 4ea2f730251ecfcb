"""Fixed-order, multi-model H∞ tuning of K∞ (what MATLAB's ``hinfstruct``/``systune`` do).

Minimise over the parameters x of a fixed-order K∞ (:class:`rigd.design.fixed_order.FixedOrder`)

    γ(x) = max_i max_ω σ̄(T_i(e^{jωT}))                                          (a)
    subject to ρ(A_cl,i(x)) ≤ ρ_max for every model i                              (b)

where T_i = F_l(P_i, K) is the closed loop of :mod:`rigd.design.hinf` (w = [d_o, W_d·d_i] →
z = [W_p p, W_u u]; with W_d = 0 the paper's N = [W_p S; W_u K S]) for plant model G_i,
evaluated as the loop runs: G_i discretised by zero-order hold at fs, K(z) the prewarped
Tustin of K(s) (K(z) at e^{jωT} is K(s) at the warped frequency, exactly), and (b) is the
spectral radius of the discrete closed loop (the delay the ZOH plant carries included).

The max over the frequency grid and the models is smoothed by a log-sum-exp of log σ̄ with a
rising sharpness β (continuation: 30 → 300), each stage by L-BFGS-B with finite-difference
gradients; (b) enters as a barrier −μ·log(ρ_max − ρ) that is +∞ outside, so an accepted step
never leaves the stable set. A start that does not stabilise every model is first driven
into the stable set by minimising the largest spectral radius. Starts: the balanced-truncated
full-order controller (projected on the structure) and ``n_random`` seeded random ones; the
best result is kept. After the optimisation the peak is re-checked on a dense grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rigd.design.discretize import tustin_matrices, warp
from rigd.design.fixed_order import FixedOrder, freq_response
from rigd.design.hinf import OMEGA_SCALE
from rigd.design.hinf_kernel import weighted_sigma
from rigd.errors import InputError

#: largest accepted closed-loop spectral radius (decay ≥ 2.5 s⁻¹ at 5 kHz)
RHO_MAX = 0.9995
#: κ of the penalty of the hard bound on σ̄(S_o) (see :meth:`Problem.lse`)
PENALTY = 10.0


@dataclass
class DiscreteModel:
    """A plant model of the set, ZOH-discretised, with its response on the grid."""

    label: str
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Gf: np.ndarray            # (n_f, 2, 2) G(e^{jωT}) on the optimisation grid


def discretize_model(G, fs_hz: float, f_hz: np.ndarray, label: str) -> DiscreteModel:
    """ZOH of a continuous 2×2 plant (D = 0) and its response on ``f_hz``."""
    from rigd.design.discretize import zoh
    from rigd.design.robustness import freq_response as fr

    Gd = zoh(G, fs_hz)
    if np.any(np.abs(Gd.D) > 0):
        raise InputError("plant models must be strictly proper (D = 0)", label)
    return DiscreteModel(label, np.asarray(Gd.A), np.asarray(Gd.B), np.asarray(Gd.C),
                         fr(Gd, f_hz))


@dataclass
class Problem:
    """Everything the cost needs, precomputed (weights on the grid, models)."""

    structure: FixedOrder
    models: list[DiscreteModel]
    f_hz: np.ndarray
    fs_hz: float
    prewarp_hz: float | None
    Wp: np.ndarray            # (n_f,) |W_p| (diagonal, equal channels)
    Wu: np.ndarray            # (n_f,) |W_u|
    wd: float
    s_max: float | None = None    # hard bound on σ̄(S_o) at every model and frequency
    s_warp: np.ndarray = field(init=False)

    def __post_init__(self):
        self.s_warp = 1j * warp(self.f_hz, self.fs_hz, self.prewarp_hz) / OMEGA_SCALE
        Gf = np.stack([m.Gf for m in self.models])              # (n_models, n_f, 2, 2)
        self._G = np.ascontiguousarray(Gf)
        self._wp2 = np.ascontiguousarray(self.Wp ** 2, dtype=float)
        self._wu2 = np.ascontiguousarray(self.Wu ** 2, dtype=float)
        Y = np.eye(2)[None, None] + self.wd ** 2 * (Gf @ Gf.conj().transpose(0, 1, 3, 2))
        self._y = tuple(np.ascontiguousarray(v) for v in
                        (Y[..., 0, 0].real, Y[..., 0, 1], Y[..., 1, 1].real))
        # the closed loops of every model in one stack (one eigvals call per evaluation)
        self._stack = None
        if len({m.A.shape for m in self.models}) == 1:
            self._stack = tuple(np.stack([getattr(m, k) for m in self.models])
                                for k in ("A", "B", "C"))
            n, nk = self.models[0].A.shape[0], self.structure.n
            self._acl = np.empty((len(self.models), n + nk, n + nk))

    # --- pieces ---------------------------------------------------------------------
    def K_grid(self, x) -> np.ndarray:
        """K(e^{jωT}) on the grid (n_f, 2, 2)."""
        return self.structure.response(x, self.s_warp)

    def sigma(self, x) -> np.ndarray:
        """σ̄(T_i) (n_models, n_f): the weighted closed loop of every model on the grid
        (:func:`rigd.design.hinf_kernel.weighted_sigma`)."""
        return self.sigma_of(self.K_grid(x))

    def sigma_of(self, K: np.ndarray) -> np.ndarray:
        """σ̄(T_i) for any controller given by its response K(e^{jωT}) (n_f, 2, 2)."""
        return self.sigmas_of(K)[0]

    def sigmas_of(self, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(σ̄(T_i), σ̄(S_o,i)), each (n_models, n_f), for the response K(e^{jωT})."""
        out = np.empty((len(self.models), len(self.f_hz)))
        out_s = np.empty_like(out)
        weighted_sigma(np.ascontiguousarray(K, dtype=complex), self._G, *self._y, self._wp2,
                       self._wu2, out, out_s)
        return out, out_s

    def spectral_radius(self, x) -> np.ndarray:
        """ρ of the discrete closed loop (ZOH plant, Tustin K) of every model."""
        Ad, Bd, Cd, Dd = tustin_matrices(*self.structure.matrices(x), self.fs_hz,
                                         self.prewarp_hz, OMEGA_SCALE)
        if self._stack is None:      # models of different orders: one by one
            rho = np.empty(len(self.models))
            for i, m in enumerate(self.models):
                Acl = np.block([[m.A - m.B @ Dd @ m.C, m.B @ Cd], [-Bd @ m.C, Ad]])
                rho[i] = np.max(np.abs(np.linalg.eigvals(Acl)))
            return rho
        A, B, C = self._stack          # (n_models, n, n), (n_models, n, 2), (n_models, 2, n)
        n = A.shape[1]
        Acl = self._acl
        Acl[:, :n, :n] = A - B @ Dd @ C
        Acl[:, :n, n:] = B @ Cd
        Acl[:, n:, :n] = -Bd @ C
        Acl[:, n:, n:] = Ad
        return np.max(np.abs(np.linalg.eigvals(Acl)), axis=1)

    # --- costs ----------------------------------------------------------------------
    def smooth_gamma(self, x, beta: float) -> float:
        """log-sum-exp_β of log σ̄ over models × grid (→ log γ as β → ∞); +∞ when a
        closed loop of the set has ρ ≥ :data:`RHO_MAX`."""
        rho = self.spectral_radius(x)
        if not np.all(np.isfinite(rho)) or np.any(rho >= RHO_MAX):
            return np.inf
        return self.lse(x, beta)

    def lse(self, x, beta: float) -> float:
        """log-sum-exp_β of ln σ̄(T) over models × grid (≥ ln γ, → ln γ as β → ∞), plus the
        penalty κ·Σ max(0, ln(σ̄(S_o)/s_max))² of the hard bound on σ̄(S_o) (if any)."""
        sig, sig_s = self.sigmas_of(self.K_grid(x))
        g = np.log(sig.ravel())
        gmax = g.max()
        pen = 0.0
        if self.s_max is not None:
            pen = PENALTY * float(np.sum(np.maximum(np.log(sig_s / self.s_max), 0.0) ** 2))
        return float(gmax + np.log(np.sum(np.exp(beta * (g - gmax)))) / beta) + pen

    def peak_s(self, x) -> float:
        """max σ̄(S_o) over models and grid."""
        return float(self.sigmas_of(self.K_grid(x))[1].max())

    def smooth_rho(self, x, beta: float = 200.0) -> float:
        r = self.spectral_radius(x)
        rmax = r.max()
        return float(rmax + np.log(np.sum(np.exp(beta * (r - rmax)))) / beta)


@dataclass
class TuneResult:
    x: np.ndarray
    gamma: float                        # max σ̄ over models and grid (unsmoothed)
    gamma_per_model: list[float]
    rho_per_model: list[float]
    starts: list[dict]
    n_evals: int


def _fd_grad(fun, x, f0, h=1e-6):
    g = np.empty_like(x)
    for k in range(len(x)):
        xk = x.copy()
        step = h * max(1.0, abs(x[k]))
        xk[k] += step
        fk = fun(xk)
        if not np.isfinite(fk):
            xk[k] -= 2 * step
            fk = fun(xk)
            g[k] = (f0 - fk) / step if np.isfinite(fk) else 0.0
        else:
            g[k] = (fk - f0) / step
    return g


def _bfgs(fun, x0, maxiter: int, counter: list, grad_fun=None, max_step: float = 1.0,
          tol: float = 1e-5, done=None):
    """BFGS with a backtracking (Armijo) line search that treats +∞ (a step out of the
    stable set) as "too far"; gradients by forward differences of ``grad_fun`` (default
    ``fun``: only σ̄ is needed for them, the stability check only for accepted steps).
    Quasi-Newton with an inexact line search copes with the kinks of a max (Lewis & Overton,
    2013); the log-sum-exp smoothing keeps them mild. Stops after ``maxiter`` iterations or
    when 4 successive iterations gained less than ``tol`` (relative), or as soon as
    ``done(f)`` is true."""
    grad_fun = grad_fun or fun

    def grad(x):
        f0 = grad_fun(x)
        counter[0] += len(x) + 1
        return _fd_grad(grad_fun, x, f0)

    x = np.asarray(x0, float).copy()
    f = fun(x)
    counter[0] += 1
    if not np.isfinite(f):
        return x
    g = grad(x)
    H = None
    slow = 0
    for _ in range(maxiter):
        p = -(g if H is None else H @ g)
        if g @ p >= 0:                      # lost descent: restart from steepest descent
            H, p = None, -g
        nrm = np.linalg.norm(p)
        if nrm > max_step:
            p *= max_step / nrm
        t = 1.0
        while True:
            xn = x + t * p
            fn = fun(xn)
            counter[0] += 1
            if np.isfinite(fn) and fn <= f + 1e-4 * t * (g @ p):
                break
            t *= 0.5
            if t < 1e-8:
                return x
        gn = grad(xn)
        sv, yv = xn - x, gn - g
        sy = sv @ yv
        if sy > 1e-12:
            if H is None:
                H = np.eye(len(x)) * sy / (yv @ yv)
            rho = 1.0 / sy
            V = np.eye(len(x)) - rho * np.outer(sv, yv)
            H = V @ H @ V.T + rho * np.outer(sv, sv)
        slow = slow + 1 if f - fn < tol * max(1.0, abs(f)) else 0
        x, f, g = xn, fn, gn
        if slow >= 4 or (done is not None and done(f)):
            break
    return x


def stabilize(prob: Problem, x0, counter, maxiter: int = 200):
    """Drive x0 into the stable set (all ρ < RHO_MAX) by minimising the largest ρ."""
    x = np.asarray(x0, float)
    for _ in range(3):
        if np.all(prob.spectral_radius(x) < RHO_MAX - 1e-4):
            return x
        x = _bfgs(prob.smooth_rho, x, maxiter, counter,
                  done=lambda f: f < RHO_MAX - 2e-4)
    return x if np.all(prob.spectral_radius(x) < RHO_MAX) else None


def tune(prob: Problem, starts: list[np.ndarray], *, screen_iters: int = 25,
         polish=((30.0, 40), (100.0, 40), (300.0, 40)), keep: int = 2) -> TuneResult:
    """Multi-start structured H∞ tuning (see module docstring).

    Every start is stabilised and run ``screen_iters`` BFGS iterations at β = 30; the ``keep``
    best go on through the ``polish`` stages (β, iterations); the lowest γ wins.

    Raises
    ------
    InputError
        When no start can be made to stabilise every model of the set.
    """
    counter = [0]
    log, cands = [], []
    b0 = polish[0][0]
    for k, x0 in enumerate(starts):
        xs = stabilize(prob, x0, counter)
        if xs is None:
            log.append({"start": k, "stabilized": False})
            continue
        x = _bfgs(lambda z: prob.smooth_gamma(z, b0), xs, screen_iters, counter,
                  grad_fun=lambda z: prob.lse(z, b0))
        g = float(prob.sigma(x).max())
        log.append({"start": k, "stabilized": True, "gamma_screen": g})
        cands.append((g, k, x))
    if not cands:
        raise InputError(f"a {prob.structure.n}-state controller (zeros at DC: "
                         f"{prob.structure.m}) stabilises not all {len(prob.models)} "
                         f"models of the design set from any of {len(starts)} starts", "design")
    best = None
    for _g, k, x in sorted(cands, key=lambda c: c[0])[:keep]:
        for b, it in polish:
            x = _bfgs(lambda z, b=b: prob.smooth_gamma(z, b), x, it, counter,
                      grad_fun=lambda z, b=b: prob.lse(z, b))
        g = float(prob.sigma(x).max())
        log[k]["gamma"] = g
        if best is None or g < best[1]:
            best = (x, g)
    x, g = best
    sig = prob.sigma(x)
    return TuneResult(x=x, gamma=g, gamma_per_model=[float(v) for v in sig.max(axis=1)],
                      rho_per_model=[float(v) for v in prob.spectral_radius(x)],
                      starts=log, n_evals=counter[0])


def project(structure: FixedOrder, K, rng: np.random.Generator | None = None) -> np.ndarray:
    """Parameters of ``structure`` closest to the continuous controller ``K`` (same order).

    K is brought to real modal form in the scaled unit; each complex pole pair becomes a
    block (ω_n, ζ), real poles are paired; B and Ĉ are fitted by least squares to K's
    frequency response in the scaled unit (the DC zeros then hold by construction).
    """
    A = np.asarray(K.A) / OMEGA_SCALE
    ev = np.linalg.eigvals(A)
    ev = ev[np.argsort(-ev.real)]
    pairs = []
    cplx = [e for e in ev if e.imag > 1e-9]
    real = sorted([e.real for e in ev if abs(e.imag) <= 1e-9])
    for e in cplx:
        pairs.append((abs(e), max(-e.real / abs(e), 1e-3)))
    while len(real) >= 2:
        a, b = real.pop(), real.pop()
        wn = np.sqrt(abs(a * b))
        pairs.append((wn, max(-(a + b) / (2 * wn), 1e-3)))
    rp = abs(real[0]) if real else None
    pairs = pairs[:structure.n_pairs]
    while len(pairs) < structure.n_pairs:
        pairs.append((1.0, 0.5))
    if structure.n % 2 and rp is None:
        rp = 1.0
    n, ny, nu = structure.n, structure.ny, structure.nu
    x = structure.pack(pairs, rp, np.zeros((n, ny)), np.zeros((nu, n)))
    # fit B, Ĉ to K's response by Gauss-Newton on the bilinear parameters
    from scipy.optimize import least_squares

    s = 1j * np.linspace(0.5, 2.5, 60)
    from rigd.design.robustness import freq_response as fr

    Kf = fr(K, s.imag * OMEGA_SCALE / (2 * np.pi))
    k0 = 2 * structure.n_pairs + n % 2
    rng = rng or np.random.default_rng(0)

    def res(v):
        z = x.copy()
        z[k0:] = v
        d = (freq_response(*structure.matrices(z), s) - Kf).ravel()
        return np.r_[d.real, d.imag]

    v = least_squares(res, rng.normal(0, 0.3, len(x) - k0), max_nfev=400).x
    x[k0:] = v
    return x


def random_start(structure: FixedOrder, rng: np.random.Generator, band_scaled=(0.7, 1.9),
                 gain: float = 0.3) -> np.ndarray:
    """A random controller: pole pairs in the band (scaled unit), ζ in 0.1–1, small B, Ĉ."""
    pairs = [(rng.uniform(*band_scaled), np.exp(rng.uniform(np.log(0.1), 0.0)))
             for _ in range(structure.n_pairs)]
    rp = rng.uniform(*band_scaled) if structure.n % 2 else None
    n = structure.n
    return structure.pack(pairs, rp, rng.normal(0, np.sqrt(gain), (n, structure.ny)),
                          rng.normal(0, np.sqrt(gain), (structure.nu, n)))
