"""Diagnosis context and results of one effect on one record.

:class:`Finding` (what the diagnosis concluded), :class:`CannotReveal` (why a record cannot
show an effect) and :class:`Context` (everything an effect's signature needs about one fitted
sub-model). The data helpers it uses (:func:`rigd.ident.iddata.replace_inputs`,
:func:`rigd.ident.iddata.get_phi`) live with the identification data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.effects.state_level import simulate_state
from rigd.ident.iddata import get_phi, replace_inputs
from rigd.ident.model import base_of


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
        Validation fit (%) after adding the effect and refitting (None in the JSON when not
        refitted or not finite). A refit worse than the model it extends, below 0 % or
        diverged carries ``evidence["refit_flag"]`` (:func:`rigd.ident.figures.refit_flag`;
        ``refit_flag`` in the JSON): never significant, listed last, not ranked.
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
        # an effect registered under a site-specific name (``hysteresis_restoring``) is
        # reported under its canonical catalogue name with the site and the --add name
        reported = self.evidence.get("reported_as")
        d: dict[str, Any] = {
            "effect": reported or self.effect,
            "significant": bool(self.significant),
            "score": round(float(self.score), 4),
            "explanation": self.explanation,
            "fit_percent_with": (None if self.fit_percent_with is None
                                 or not math.isfinite(self.fit_percent_with)
                                 else round(float(self.fit_percent_with), 3)),
            "signature_score": round(float(self.signature_score), 4),
        }
        if "site" in self.evidence:
            d["site"] = self.evidence["site"]
        if "refit_flag" in self.evidence:  # rigd.ident.figures.refit_flag: not ranked
            d["refit_flag"] = self.evidence["refit_flag"]
        if reported:
            d["add"] = self.effect
        if with_submodel:
            d["submodel"] = self.submodel
        return d


@dataclass
class CannotReveal:
    """An effect this record cannot show, why, and the experiment that would.

    ``partial``: the record can tell part of the effect's range (e.g. fast creep but not
    slow creep): it is listed *and* still tested.
    """

    effect: str
    why: str
    experiment: str
    submodel: str = "generic"
    partial: bool = False
    #: an evidence code and its numbers (rigd.diagnose.advice words ``why`` and
    #: ``experiment`` from them, for the record's domain); None: the texts are given
    code: str | None = None
    evidence: dict[str, Any] = field(default_factory=dict)

    def to_json(self, with_submodel: bool = True) -> dict[str, Any]:
        d: dict[str, Any] = {"effect": self.effect, "why": self.why,
                             "experiment": self.experiment}
        if self.partial:
            d["partial"] = True
        if with_submodel:
            d["submodel"] = self.submodel
        return d


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
    #: the record's domain (rigd.diagnose.domain: rotor, mechanical, process, generic) and
    #: the base model's time constants (s, slowest first): what the advice is sized by
    domain: str = "generic"
    time_constants_s: list[float] = field(default_factory=list)
    _zero_response: np.ndarray | None = None
    #: per-context results shared by the effects (the base model's sensitivities of
    #: rigd.effects.detectability)
    cache: dict[str, Any] = field(default_factory=dict, repr=False)

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

        The model-filtered regressor of an effect acting where the input acts (force, valve
        position): ``v`` is simulated at the record's own input amplitude and the result
        scaled back, so ``c·v`` (c > 0) gives ``c`` times the result whatever the model,
        and for a linear model it is exactly the (linear) response to ``v``.

        Parameters
        ----------
        v : ndarray (n, nu) or (n,)
            Signal in the units of the model inputs (V, N, ...; a derivative in input
            units/s), fed into every input, or (n,) into input ``channel`` only.
        channel : int, optional
            Input fed by a 1-D ``v`` (default 0).

        Returns
        -------
        ndarray (n, ny)
            ``(M(s·v) − M(0)) / s`` in output units per unit of ``v``: ``M(x)`` is the model
            simulated with inputs ``x``, ``M(0)`` its free response (initial state).

        Notes
        -----
        The scale ``s`` is one positive scalar per call: each fed input channel j (a column
        of ``v`` not identically zero) has the ratio r_j = rms(u_j) / rms(v_j) of the
        record's input to the signal replacing it, and s = min_j r_j, so that ``s·v`` is
        at most the record's own amplitude on every input and at it on one (the operating
        range the model was fitted on). One scalar, so a linear model's response is
        unchanged (``M(s·v) − M(0) = s·(M(v) − M(0))``); per-channel ratios, so inputs
        in different units are not mixed (an rms over all inputs fed would be set by the
        one in the smallest unit). For a nonlinear model (cubic stiffness, restoring-force
        hysteresis) the regressor is its response at the record's operating amplitude,
        the same whatever the units of ``v``: fed at its own size, the input derivative
        of ``actuator_dynamics`` (input units/s, × fs) drove a Duffing model far past its
        fitted range at fs = 1 kHz and not at 1 Hz (docs/diagnose.md, "Invariance"). A
        channel whose input is identically zero gives no ratio; when none does, s = 1.
        """
        v = np.asarray(v, dtype=float)
        if v.ndim == 1:
            full = np.zeros((v.shape[0], self.nu))
            full[:, channel or 0] = v
            v = full
        if self._zero_response is None:
            zero = replace_inputs(self.data, np.zeros_like(self.u))
            self._zero_response = np.asarray(self.structure.simulate(self.theta, zero))
        s = input_scale(self.u, v)
        out = np.asarray(self.structure.simulate(self.theta, replace_inputs(self.data, s * v)))
        return (out - self._zero_response) / s

    def through_force(self, v: np.ndarray, axis: int) -> np.ndarray:
        """Response (n, ny) of the fitted mechanical model to ``v`` (n,) added to the
        mass-normalised force (acceleration) of output axis ``axis``:
        p̈ + D ṗ + K p = B u + e_axis v.

        Falls back to :meth:`through_model` on input ``axis`` for structures without a
        continuous state-space form.
        """
        base = base_of(self.structure)
        # no [p, ṗ] states (a general LTI model has modal ones: rigd.effects.base.is_mechanical)
        if "mechanical" not in base.carries:
            return self.through_model(v, min(axis, self.nu - 1))
        A, B, C, _, _ = self.structure.continuous(self.theta)
        nx = A.shape[0]
        Bf = np.zeros((nx, 1))
        Bf[nx // 2 + axis, 0] = 1.0  # states [p, ṗ]
        return simulate_state(A, Bf, C, None, None, None, self.fs,
                              np.asarray(v, float).reshape(-1, 1))

    def label(self, i: int, kind: str = "out") -> str:
        names = self.output_names if kind == "out" else self.input_names
        return names[i] if i < len(names) else f"{kind}{i + 1}"


def input_scale(u: np.ndarray, v: np.ndarray) -> float:
    """Scale s that brings ``v`` (n, nu) to the amplitude of the inputs ``u`` (n, nu) it
    replaces: min over the channels fed (v_j not all zero, u_j not all zero) of
    rms(u_j) / rms(v_j); 1 when no channel gives a finite positive ratio. Dimensionless
    when ``v`` is in the inputs' units (see :meth:`Context.through_model`)."""
    ru = np.sqrt(np.mean(np.square(u), axis=0))
    rv = np.sqrt(np.mean(np.square(v), axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ru / rv
    r = r[(rv > 0) & np.isfinite(r) & (r > 0)]
    return float(np.min(r)) if r.size else 1.0
