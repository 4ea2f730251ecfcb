"""Types shared by every physical effect: :class:`Effect`, :class:`Finding`, :class:`Context`.

An *effect* is one physical phenomenon a grey-box model may leave out (catalogue in
``../shared/DESIGN.md``). Each effect module defines one :class:`Effect` subclass with

* ``reveal(ctx)``: ``None`` when this record can show the effect, else a
  :class:`CannotReveal` saying why not and which experiment would;
* ``regressors(ctx)``: the effect's *signature* — the first-order change of the model output
  that the effect's parameters would produce, each an ``(n, ny)`` array. The residual is
  regressed on them (estimation part) and the share of the validation residual energy they
  explain is the signature score (a score/Lagrange-multiplier test, made honest by scoring
  out of sample);
* ``explain(ctx, fit)``: plain-language evidence a rig engineer can check;
* ``extend(structure)``: the base structure plus the effect's parameters, fitted with the
  rest by ``rigd identify --add NAME`` and by the diagnosis refit.

Structures follow the contract of ``docs/ARCHITECTURE.md``: ``names``, ``theta0(data)``,
``simulate(theta, data) -> (n, ny)``; data carry ``inputs`` (n, nu), ``outputs`` (n, ny),
``fs`` and optionally the shaft angle ``phi``.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np


# --------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------
@dataclass
class Finding:
    """What the diagnosis concluded about one effect on one sub-model.

    Attributes
    ----------
    effect : str
        Canonical effect name.
    score : float
        Share (0..1) of the base model's validation residual energy the effect removes:
        from the refit when one was made, else from the signature regression.
    significant : bool
        Signature significant *and* (when refitted) the refit lowers the validation error.
    explanation : str
        Plain-language physics and evidence.
    submodel : str
        ``actuator``, ``bearing`` or ``generic``.
    signature_score : float
        Out-of-sample share of residual energy explained by the linearised signature.
    fit_percent_with : float or None
        Validation fit (%) after adding the effect and refitting.
    evidence : dict
        Numbers behind the explanation (frequencies, amplitudes, lags...).
    """

    effect: str
    score: float
    significant: bool
    explanation: str
    submodel: str = "generic"
    signature_score: float = 0.0
    fit_percent_with: float | None = None
    evidence: dict[str, Any] = field(default_factory=dict)

    def to_json(self, with_submodel: bool = True) -> dict[str, Any]:
        d: dict[str, Any] = {
            "effect": self.effect,
            "significant": bool(self.significant),
            "score": round(float(self.score), 4),
            "explanation": self.explanation,
            "fit_percent_with": (None if self.fit_percent_with is None
                                 else round(float(self.fit_percent_with), 3)),
            "signature_score": round(float(self.signature_score), 4),
        }
        if with_submodel:
            d["submodel"] = self.submodel
        return d


@dataclass
class CannotReveal:
    """An effect this record cannot show, why, and the experiment that would."""

    effect: str
    why: str
    experiment: str
    submodel: str = "generic"

    def to_json(self, with_submodel: bool = True) -> dict[str, Any]:
        d = {"effect": self.effect, "why": self.why, "experiment": self.experiment}
        if with_submodel:
            d["submodel"] = self.submodel
        return d


# --------------------------------------------------------------------------------------
# data helpers (work with rigd.ident.IdData or any object with inputs/outputs/fs)
# --------------------------------------------------------------------------------------
def replace_inputs(data: Any, u: np.ndarray) -> Any:
    """A shallow copy of ``data`` whose ``inputs`` are ``u`` (n, nu)."""
    u = np.asarray(u, dtype=float)
    if hasattr(data, "with_inputs"):
        return data.with_inputs(u)
    if dataclasses.is_dataclass(data):
        return dataclasses.replace(data, inputs=u)
    new = copy.copy(data)
    new.inputs = u
    return new


def get_phi(data: Any) -> np.ndarray | None:
    """The shaft angle (rad) carried by ``data``, or None."""
    phi = getattr(data, "phi", None)
    if phi is None:
        aux = getattr(data, "aux", None) or {}
        phi = aux.get("phi") if isinstance(aux, dict) else None
    return None if phi is None else np.asarray(phi, dtype=float)


# --------------------------------------------------------------------------------------
# diagnosis context
# --------------------------------------------------------------------------------------
@dataclass
class Context:
    """Everything an effect's signature needs about one sub-model fitted to one record.

    Attributes
    ----------
    submodel : str
        ``actuator`` (r -> u), ``bearing`` (u -> e) or ``generic``.
    data : object
        Identification data (inputs, outputs, fs, phi) of the whole record.
    structure : object
        The fitted base structure; ``theta`` its parameters.
    yhat : ndarray (n, ny)
        Base model simulation over the whole record.
    est, val : slice
        Estimation and validation parts (the base was fitted on ``est``).
    omega_hz : float
        Shaft speed Ω / 2π, Hz (0 for non-rotor records).
    resonances_hz : list of float
        Resonance frequencies of the base model.
    input_names, output_names : list of str
    """

    submodel: str
    data: Any
    structure: Any
    theta: np.ndarray
    yhat: np.ndarray
    est: slice
    val: slice
    omega_hz: float = 0.0
    resonances_hz: list[float] = field(default_factory=list)
    input_names: list[str] = field(default_factory=list)
    output_names: list[str] = field(default_factory=list)
    _zero_response: np.ndarray | None = None

    # derived ---------------------------------------------------------------------------
    @property
    def fs(self) -> float:
        return float(self.data.fs)

    @property
    def u(self) -> np.ndarray:
        return np.asarray(self.data.inputs, dtype=float)

    @property
    def y(self) -> np.ndarray:
        return np.asarray(self.data.outputs, dtype=float)

    @property
    def residual(self) -> np.ndarray:
        return self.y - self.yhat

    @property
    def phi(self) -> np.ndarray | None:
        return get_phi(self.data)

    @property
    def n(self) -> int:
        return self.y.shape[0]

    @property
    def ny(self) -> int:
        return self.y.shape[1]

    @property
    def nu(self) -> int:
        return self.u.shape[1]

    def through_model(self, v: np.ndarray, channel: int | None = None) -> np.ndarray:
        """Response (n, ny) of the fitted base model to ``v`` fed in place of its inputs.

        ``v`` is (n, nu), or (n,) fed into input ``channel`` only. The free response (initial
        state) is removed, so the result is linear in ``v``: the model-filtered regressor of
        an effect acting where the input acts (force, valve position).
        """
        v = np.asarray(v, dtype=float)
        if v.ndim == 1:
            full = np.zeros((v.shape[0], self.nu))
            full[:, channel or 0] = v
            v = full
        if self._zero_response is None:
            zero = replace_inputs(self.data, np.zeros_like(self.u))
            self._zero_response = np.asarray(self.structure.simulate(self.theta, zero))
        out = np.asarray(self.structure.simulate(self.theta, replace_inputs(self.data, v)))
        return out - self._zero_response

    def through_force(self, v: np.ndarray, axis: int) -> np.ndarray:
        """Response (n, ny) of the fitted mechanical model to ``v`` (n,) added to the
        mass-normalised force (acceleration) of output axis ``axis``: p̈ + D ṗ + K p = B u + e_axis v.

        Falls back to :meth:`through_model` on input ``axis`` for structures without a
        continuous state-space form.
        """
        from rigd.effects._state import simulate_state

        cont = getattr(self.structure, "continuous", None)
        if not callable(cont):
            return self.through_model(v, min(axis, self.nu - 1))
        A, B, C, _, _ = cont(self.theta)
        nx = A.shape[0]
        Bf = np.zeros((nx, 1))
        Bf[nx // 2 + axis, 0] = 1.0  # states [p, ṗ]
        return simulate_state(A, Bf, C, None, None, None, self.fs,
                              np.asarray(v, float).reshape(-1, 1))

    def label(self, i: int, kind: str = "out") -> str:
        names = self.output_names if kind == "out" else self.input_names
        return names[i] if i < len(names) else f"{kind}{i + 1}"


# --------------------------------------------------------------------------------------
# structure extension
# --------------------------------------------------------------------------------------
class ExtendedStructure:
    """A base structure plus one effect's parameters (``names = base.names + effect``).

    Extending an extended structure nests, so effects compose: ``--add delay,runout``
    (:func:`rigd.effects.extend` orders them state-level first). State-level effects
    (``level = "state"``) act on the continuous-time mechanical model when the base exposes
    ``continuous(theta) -> (A, B, C, D, x0)``, else by fixed-point iteration.
    """

    def __init__(self, base: Any, effect: "Effect"):
        self.base = base
        self.effect = effect
        self._enames = list(effect.param_names(base))
        self.names = list(base.names) + self._enames
        self.effects = list(getattr(base, "effects", [])) + [effect.name]
        self._state_ok: bool | None = None

    @property
    def nb(self) -> int:
        return len(self.base.names)

    def theta0(self, data: Any) -> np.ndarray:
        return np.concatenate([np.asarray(self.base.theta0(data), float),
                               np.asarray(self.effect.theta0_effect(self.base, data), float)])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower/upper bounds (base ones if it has them, else unbounded)."""
        if hasattr(self.base, "bounds"):
            lb, ub = self.base.bounds()
        else:
            lb, ub = np.full(self.nb, -np.inf), np.full(self.nb, np.inf)
        elb, eub = self.effect.param_bounds(self.base)
        return np.concatenate([lb, elb]), np.concatenate([ub, eub])

    # --- simulation ---------------------------------------------------------------------
    def simulate(self, theta: np.ndarray, data: Any, hooks: Any = None) -> np.ndarray:
        """Simulate; ``hooks`` (rigd.ident.simulate.Hooks) are passed down to the base.

        State-level effects set their hooks (cubic stiffness ``k3``, ``dK``/``dD``) for the
        mechanical base simulator; a base that takes no hooks gets the effect by fixed-point
        iteration on its batch simulation instead.
        """
        from rigd.effects._state import fixed_point

        theta = np.asarray(theta, dtype=float)
        tb, te = theta[:self.nb], theta[self.nb:]
        takes = accepts_hooks(self.base)
        if self.effect.level == "state" and takes:
            from rigd.ident.simulate import Hooks

            hooks = hooks if hooks is not None else Hooks()
            self.effect.apply_hooks(te, hooks, data)
            return np.asarray(self.base.simulate(tb, data, hooks), dtype=float)

        def sim(d: Any) -> np.ndarray:
            if hooks is not None and takes:
                return np.asarray(self.base.simulate(tb, d, copy.copy(hooks)), dtype=float)
            return np.asarray(self.base.simulate(tb, d), dtype=float)

        if self.effect.level != "state":
            return self.effect.simulate_with(sim, te, data, self.base)
        fs, nu = float(data.fs), np.asarray(data.inputs).shape[1]
        return fixed_point(sim, data, lambda p: self.effect.feedback(p, te, fs, nu))

    def ss(self, theta: np.ndarray):
        return self.base.ss(np.asarray(theta, float)[:self.nb])

    def continuous(self, theta: np.ndarray):
        return self.base.continuous(np.asarray(theta, float)[:self.nb])

    def readouts(self, theta: np.ndarray) -> dict[str, Any]:
        theta = np.asarray(theta, float)
        out = dict(self.base.readouts(theta[:self.nb])) if hasattr(self.base, "readouts") else {}
        out.update({n: float(v) for n, v in zip(self._enames, theta[self.nb:])})
        return out

    def spec(self) -> dict[str, Any]:
        d = dict(self.base.spec()) if hasattr(self.base, "spec") else {}
        d["effects"] = list(self.effects)
        return d

    def __getattr__(self, item: str) -> Any:  # resonances, ny, ... of the base
        if item in ("base", "effect") or item.startswith("__"):
            raise AttributeError(item)
        return getattr(self.base, item)


class Effect:
    """Base class of one physical effect (subclass per module, register in REGISTRY).

    Class attributes
    ----------------
    name : str
        Canonical name (``../shared/DESIGN.md``).
    submodels : tuple of str
        Sub-models the effect concerns (``actuator``, ``bearing``, ``generic``).
    physics : str
        One line of physics for the report.
    min_score : float
        Minimum out-of-sample share of residual energy explained for significance.
    """

    name: str = "effect"
    level: str = "input"  # "state" (mechanical model), "input" (pre-transform), "output"
    submodels: tuple[str, ...] = ("actuator", "bearing", "generic")
    physics: str = ""
    min_score: float = 0.05

    # --- diagnosis ----------------------------------------------------------------------
    def reveal(self, ctx: Context) -> CannotReveal | None:
        """None if the record can reveal the effect, else why not and what would."""
        return None

    def regressors(self, ctx: Context) -> list[np.ndarray]:
        """Signature regressors, each (n, ny): first-order output change per parameter."""
        raise NotImplementedError

    def explain(self, ctx: Context, sig: "SignatureFit") -> tuple[str, dict]:
        """Plain-language explanation and evidence numbers."""
        return f"{self.physics}; explains {100 * sig.score:.0f} % of the residual", {}

    def signature(self, ctx: Context) -> "SignatureFit":
        """Regress the residual on :meth:`regressors` (est part), score on validation part."""
        return signature_fit(ctx, self.regressors(ctx))

    # --- model extension ----------------------------------------------------------------
    def extend(self, structure: Any) -> ExtendedStructure:
        """The structure with this effect's parameters added (fitted with the rest)."""
        return ExtendedStructure(structure, self)

    def param_names(self, base: Any) -> list[str]:
        raise NotImplementedError

    def theta0_effect(self, base: Any, data: Any) -> np.ndarray:
        return np.zeros(len(self.param_names(base)))

    def param_bounds(self, base: Any) -> tuple[np.ndarray, np.ndarray]:
        k = len(self.param_names(base))
        return np.full(k, -np.inf), np.full(k, np.inf)

    def simulate_with(self, sim: Callable[[Any], np.ndarray], theta_e: np.ndarray, data: Any,
                      base: Any) -> np.ndarray:
        """Output of the extended model, given ``sim(data) -> (n, ny)`` of the base
        (input- and output-level effects)."""
        raise NotImplementedError

    def apply_hooks(self, theta_e: np.ndarray, hooks: Any, data: Any) -> None:
        """State-level effects: edit ``hooks`` (rigd.ident.simulate.Hooks) in place."""
        raise NotImplementedError

    def feedback(self, p: np.ndarray, theta_e: np.ndarray, fs: float, nu: int) -> np.ndarray:
        """State-level effects without a state model: input correction u' − u from p."""
        raise NotImplementedError

    def implausible(self, ctx: Context, theta_e: np.ndarray) -> str | None:
        """Why the refitted effect is not physically what its name says, else None.

        A refit can improve the fit with parameter values that do not describe the named
        physics (e.g. a "transport delay" of a twentieth of a sample soaking up unmodelled fast
        dynamics). Such an effect is not named significant; the improvement is reported as
        unexplained structure with this text, never forced onto the name.
        """
        return None

    def warm_start(self, ctx: Context, sig: "SignatureFit") -> np.ndarray | None:
        """Effect parameters to start the refit from (default: theta0_effect)."""
        return None


# --------------------------------------------------------------------------------------
# signature regression
# --------------------------------------------------------------------------------------
@dataclass
class SignatureFit:
    """Result of regressing the residual on an effect's regressors.

    ``score`` is 1 − ‖r_val − Φ_val β‖² / ‖r_val‖² clipped to [0, 1] (out of sample), ``f_p``
    the p-value of the F test on the estimation part with an effective sample size
    corrected for the residual's autocorrelation.
    """

    score: float
    beta: np.ndarray
    f_p: float
    k: int
    score_est: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def _weights(ctx: Context) -> np.ndarray:
    """Per-output weights 1/std(y) so that every output counts alike (as the mean fit)."""
    s = np.std(ctx.y[ctx.est], axis=0)
    s[s == 0] = 1.0
    return 1.0 / s


def effective_n(r: np.ndarray, max_lag: int = 200) -> float:
    """Effective number of independent samples of a (n,) series (Bartlett's formula)."""
    r = r - r.mean()
    n = r.shape[0]
    if n < 4 or not np.any(r):
        return float(n)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(r, nfft)
    ac = np.fft.irfft(f * np.conj(f), nfft)[:min(max_lag, n - 1) + 1]
    rho = ac / ac[0]
    # sum until the first non-positive value (initial positive sequence)
    stop = np.argmax(rho[1:] <= 0) + 1 if np.any(rho[1:] <= 0) else len(rho)
    tau = 1.0 + 2.0 * np.sum(rho[1:stop])
    return float(n / max(tau, 1.0))


def signature_fit(ctx: Context, regs: Sequence[np.ndarray], ridge: float = 1e-9) -> SignatureFit:
    """Least-squares fit of the (weighted, stacked) residual on the regressors."""
    from scipy import stats

    if not regs:
        return SignatureFit(0.0, np.zeros(0), 1.0, 0)
    w = _weights(ctx)
    r = ctx.residual * w
    Phi = np.stack([np.asarray(g, float) * w for g in regs], axis=-1)  # (n, ny, k)
    k = Phi.shape[-1]
    if not np.all(np.isfinite(Phi)) or np.max(np.abs(Phi)) > 1e100:
        # a regressor from a diverging simulation (unstable extended model) carries no
        # signature
        return SignatureFit(0.0, np.zeros(k), 1.0, k)
    re, rv = r[ctx.est].reshape(-1), r[ctx.val].reshape(-1)
    Pe, Pv = Phi[ctx.est].reshape(-1, k), Phi[ctx.val].reshape(-1, k)
    scale = np.sqrt(np.sum(Pe ** 2, axis=0))
    scale[scale == 0] = 1.0
    A = Pe / scale
    beta_s = np.linalg.solve(A.T @ A + ridge * np.eye(k), A.T @ re)
    beta = beta_s / scale
    e_est = re - Pe @ beta
    e_val = rv - Pv @ beta
    ss0_e, ss0_v = float(re @ re), float(rv @ rv)
    score = 0.0 if ss0_v == 0 else max(0.0, 1.0 - float(e_val @ e_val) / ss0_v)
    score_est = 0.0 if ss0_e == 0 else max(0.0, 1.0 - float(e_est @ e_est) / ss0_e)
    # F test with effective n from the autocorrelation of the estimation residual
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - k, 1.0)
    sse = max(float(e_est @ e_est), 1e-300)
    F = ((ss0_e - sse) / k) / (sse / dof)
    p = float(stats.f.sf(max(F, 0.0), k, dof))
    return SignatureFit(score, beta, p, k, score_est)


def accepts_hooks(structure: Any) -> bool:
    """True if ``structure.simulate`` takes a third ``hooks`` argument (rigd.ident bases and
    wrappers around them)."""
    import inspect

    if isinstance(structure, ExtendedStructure):
        return accepts_hooks(structure.base)
    try:
        return "hooks" in inspect.signature(structure.simulate).parameters
    except (TypeError, ValueError):
        return False


def dims(base: Any) -> tuple[int, int]:
    """(ny, nu) of a structure: its ``ny``/``nu`` attributes or the lengths of its
    ``outputs``/``inputs`` name lists."""
    ny = getattr(base, "ny", None)
    nu = getattr(base, "nu", None)
    if ny is None:
        ny = len(getattr(base, "outputs", None) or getattr(base, "output_names", []))
    if nu is None:
        nu = len(getattr(base, "inputs", None) or getattr(base, "input_names", []))
    if not ny or not nu:
        raise TypeError(f"structure {type(base).__name__} does not tell its numbers of "
                        "inputs and outputs (ny/nu)")
    return int(ny), int(nu)
