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

An effect acts through blocks (``sites``: :meth:`Effect.input_block`,
:meth:`Effect.output_block`, :meth:`Effect.state_block`) that :mod:`rigd.effects.compose`
puts around the base. This module holds :class:`Effect` and the helpers :func:`dims` /
:func:`is_mechanical`; the context and results live in :mod:`rigd.effects.context`, the
signature regression in :mod:`rigd.effects.signature`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rigd.effects import detectability as DT
from rigd.effects.compose import Composed, carries
from rigd.effects.context import CannotReveal, Context
from rigd.effects.scales import RecordScale
from rigd.effects.signature import SignatureFit, signature_fit

__all__ = ["Effect", "STRUCTURAL", "dims", "is_mechanical"]

#: domains of records with structures that have stiffness and restoring forces (not a
#: process of time constants: rigd.diagnose.domain)
STRUCTURAL = ("rotor", "mechanical", "generic")


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
    sites : tuple of str
        Where it acts in a composed model (:mod:`rigd.effects.compose`): ``input``
        (:meth:`input_block`), ``output`` (:meth:`output_block`), ``state``
        (:meth:`state_block`, a Lur'e feedback into the base's states), ``mode`` (a
        restoring force on one mode's coordinate of a modal base, ``state_simulate``:
        :mod:`rigd.effects.mode_site`).
    requires : tuple of str
        What the base model must carry (:func:`rigd.effects.compose.carries`):
        ``mechanical`` (a mechanical state-space model, p̈ + D ṗ + K p = B u, whose simulator
        takes the feedback of state-level effects), ``rotation`` (a shaft angle in the
        record), ``mode`` (a modal LTI base with complex pairs); :meth:`not_offered` says
        why a base cannot.
    domains : tuple of str or None
        The record domains (rigd.diagnose.domain: ``rotor``, ``mechanical``, ``process``,
        ``generic``) whose physics the effect belongs to; None: every domain (the
        domain-neutral entries). A stiffness or a restoring force is :data:`STRUCTURAL`.
    """

    name: str = "effect"
    #: where the effect acts in a composed model (rigd.effects.compose: ``input`` block before
    #: the base, ``output`` block after it, ``state`` feedback into it)
    sites: tuple[str, ...] = ()
    #: an output block that adds a path parallel to the base (y + g(u, θ)): the base's exact
    #: output sensitivities hold through it (rigd.effects.compose.Composed.output_sensitivities)
    additive_output: bool = False
    requires: tuple[str, ...] = ()
    #: effects that cannot be simulated beside this one in one composed model
    excludes: tuple[str, ...] = ()
    domains: tuple[str, ...] | None = None
    submodels: tuple[str, ...] = ("actuator", "bearing", "generic")
    physics: str = ""
    min_score: float = 0.05
    #: screened by default by ``rigd diagnose`` (the catalogue's entries are; an effect
    #: offered only on request sets False)
    screened: bool = True
    #: the refit is expensive (a state model of its own): refitted only on a decisive
    #: signature (rigd.diagnose.selection)
    costly_refit: bool = False
    #: refitted on at most this many estimation samples, the first ones of the estimation
    #: part (a window; the held-out fit is still on the whole validation part), by
    #: ``rigd diagnose`` and ``rigd identify --add`` alike, and said so (None: all of them)
    max_fit_samples: int | None = None
    #: ``state_simulate(base, theta_b, theta_e, feedback, data) -> y``: the effect simulates
    #: the model with a state model of its own (sites ``state``/``mode``); None: it has none
    state_simulate = None

    def clashes_with(self, other: Effect) -> bool:
        """True when this effect and ``other`` cannot be simulated in one composed model
        (either one's :attr:`excludes` names the other)."""
        return other.name in self.excludes or self.name in other.excludes

    # --- diagnosis ----------------------------------------------------------------------
    def not_offered(self, structure: Any, data: Any = None) -> str | None:
        """Why the base ``structure`` cannot carry this effect (None: it can): the effect
        is already in ``structure`` (a :class:`rigd.effects.compose.Composed`) or excluded
        by one there (:attr:`excludes`, either way), or a requirement (:attr:`requires`)
        the base, or the record ``data``, lacks (:func:`rigd.effects.compose.carries`;
        ``rotation`` is checked only with ``data``)."""
        inside = list(structure.effect_list)
        if self.name in (e.name for e in inside):
            return f"{self.name} is already in the model"
        for e in inside:
            if self.clashes_with(e):
                return f"{self.name} cannot be simulated beside {e.name} in one model"
        has = carries(structure, data)
        if "mechanical" in self.requires and "mechanical" not in has:
            return (f"{self.name} acts on the positions and velocities of a mechanical "
                    f"model (p̈ + D ṗ + K p = B u); the base model "
                    f"({structure.kind}) is not one")
        if "mode" in self.requires and "mode" not in has:
            return (f"{self.name} acts on one mode's coordinate of a modal model (q̈ + 2ζω q̇ "
                    f"+ ω² q + φ = b·u); the base model "
                    f"({structure.kind}) has no modal "
                    f"(complex-pair) blocks")
        if "rotation" in self.requires and "rotation" not in has:
            return (f"{self.name} is locked to the angle of a rotating part, and nothing in "
                    f"the record turns (it has no angle channel 'phi')")
        return None

    def carried_by_base(self, ctx: Context) -> Any:
        """A significant Finding when the base model of ``ctx`` already carries the effect
        (it is then named from the base, not added; e.g. a pole slower than the record is
        an integrator), else None."""
        return None

    def reveal(self, ctx: Context) -> CannotReveal | None:
        """None if the record can reveal the effect, else why not and what would."""
        return None

    def regressors(self, ctx: Context) -> list[np.ndarray]:
        """Signature regressors, each (n, ny): first-order output change per parameter."""
        raise NotImplementedError

    def explain(self, ctx: Context, sig: SignatureFit) -> tuple[str, dict]:
        """Plain-language explanation and evidence numbers."""
        return f"{self.physics}; explains {100 * sig.score:.0f} % of the residual", {}

    def signature(self, ctx: Context) -> SignatureFit:
        """The effect's signature on ``ctx``, computed once per context (reveal, the
        screening and the refit's warm start share it): :meth:`_signature`."""
        key = ("signature", self.name)
        if key not in ctx.cache:
            ctx.cache[key] = self._signature(ctx)
        return ctx.cache[key]

    def _signature(self, ctx: Context) -> SignatureFit:
        """Regress the residual on :meth:`regressors` (est part), score on validation part."""
        return signature_fit(ctx, self.regressors(ctx))

    def reveal_at_nominal(self, ctx: Context, nominal: Callable[[], list[np.ndarray]], k: int,
                          code: str, evidence: dict[str, Any]) -> CannotReveal | None:
        """The "cannot tell" rule of the regression signatures
        (:mod:`rigd.effects.detectability`): None when the residual already shows the
        signature (``seen``) or the most detectable of the ``nominal()`` signatures — the
        effect at a plausible size on this record — would be seen with ``k`` parameters;
        else a :class:`CannotReveal` with the evidence ``code``, ``evidence`` and the
        detectability's numbers (worded by rigd.diagnose.advice for the record's domain)."""
        if DT.seen(ctx, self.signature(ctx)):
            return None
        d, _ = DT.best(ctx, nominal(), k=k)
        if d.detectable:
            return None
        n_est = len(range(*ctx.est.indices(ctx.n)))
        ev = dict(evidence, record_seconds=ctx.n / ctx.fs, estimation_seconds=n_est / ctx.fs,
                  detectability={"absorbed": d.absorbed, "snr": d.snr,
                                 "fit_points": d.fit_gain, "p": d.p})
        return CannotReveal(self.name, "", "", ctx.submodel, code=code, evidence=ev)

    # --- model extension ----------------------------------------------------------------
    def extend(self, structure: Any) -> Composed:
        """The structure with this effect added (its parameters fitted with the rest): one
        flat :class:`rigd.effects.compose.Composed` (ValueError, with :meth:`not_offered`'s
        reason, when the base cannot carry it)."""
        return Composed(structure, [self])

    def param_names(self, base: Any) -> list[str]:
        raise NotImplementedError

    def theta0_effect(self, base: Any, data: Any) -> np.ndarray:
        return np.zeros(len(self.param_names(base)))

    def param_bounds(self, base: Any) -> tuple[np.ndarray, np.ndarray]:
        """Bounds that hold for any record (default: none)."""
        k = len(self.param_names(base))
        return np.full(k, -np.inf), np.full(k, np.inf)

    def param_typical(self, base: Any, rec: RecordScale) -> np.ndarray | None:
        """Typical size of each parameter on this record (the fit's step sizes for a
        parameter near 0), or None: 1 in the parameter's unit. An effect with parameters
        in seconds, Hz or signal units states them here relative to ``rec``."""
        return None

    def record_bounds(self, base: Any, rec: RecordScale) -> tuple[np.ndarray, np.ndarray]:
        """Bounds relative to the record the structure is fitted on (its rate, length,
        signal spreads; :class:`rigd.effects.scales.RecordScale`). Default:
        :meth:`param_bounds`. An effect whose bounds are times, frequencies or amplitudes
        states them here relative to ``rec``, so the fit does not depend on the units or
        the rate the record is given in."""
        return self.param_bounds(base)

    #: why :meth:`linear` has no block for this effect (a linear design model leaves it out)
    linear_note: str = "nonlinear: no small-signal linear block"

    def linear(self, G: Any, theta_e: np.ndarray, base: Any, fs: float) -> Any:
        """The continuous model ``G`` (python-control StateSpace of what lies below this
        effect; ``fs`` the record's rate, Hz, for parameters in samples) with the effect's
        small-signal linear block applied, or None when it has
        none (:attr:`linear_note` says why): what a linear design model (H∞,
        ``ModelFile.plant``) carries of the effect."""
        return None

    # --- blocks of the composition (rigd.effects.compose) -------------------------------
    def input_block(self, u: np.ndarray, theta_e: np.ndarray, data: Any) -> np.ndarray:
        """Site ``input``: the inputs (n, nu) the base (or the next input block) sees, from
        the inputs ``u`` (n, nu) of ``data``; return ``u`` itself when unchanged."""
        raise NotImplementedError

    def output_block(self, y: np.ndarray, theta_e: np.ndarray, data: Any) -> np.ndarray:
        """Site ``output``: the output (n, ny) from the base's (or the previous output
        block's) ``y``; ``data`` carries the inputs this effect's input side received."""
        raise NotImplementedError

    def state_block(self, theta_e: np.ndarray, data: Any) -> Any:
        """Site ``state``: the Lur'e feedback into a mechanical base
        (:class:`rigd.ident.feedback.MechanicalFeedback`)."""
        raise NotImplementedError

    def implausible(self, ctx: Context, theta_e: np.ndarray) -> str | None:
        """Why the refitted effect is not physically what its name says, else None.

        A refit can improve the fit with parameter values that do not describe the named
        physics (e.g. a "transport delay" of a twentieth of a sample soaking up unmodelled fast
        dynamics). Such an effect is not named significant; the improvement is reported as
        unexplained structure with this text, never forced onto the name.
        """
        return None

    def fixed_names(self, base: Any) -> list[str]:
        """Parameters of this effect no fit moves (default: none)."""
        return []

    def owns_state(self, base: Any) -> bool:
        """True when this state-level effect simulates the model itself on ``base``
        (``state_simulate``); False when, on this base, it has no state part."""
        return True

    def sensitivities(self, base: Any, theta_b: np.ndarray, theta_e: np.ndarray, data: Any,
                      idx: np.ndarray, dY: np.ndarray) -> tuple | None:
        """Where this effect simulates the model itself (a mode-site law): from the base's
        exact output sensitivities ``(idx, dY)`` (k, n, ny) on ``data``, the composed
        model's, ``(base indices, own indices, dY)`` — the base's parameters whose columns
        it gives, its own (indices into ``theta_e``) and their columns, in that order; None
        (the default): it gives none, every column is then differenced."""
        return None

    def warm_start(self, ctx: Context, sig: SignatureFit) -> np.ndarray | None:
        """Effect parameters to start the refit from (default: theta0_effect)."""
        return None

    def refit_starts(self, ctx: Context, sig: SignatureFit) -> list[np.ndarray | None]:
        """Starts of the diagnosis refit; the lowest estimation cost is kept (default: the
        one :meth:`warm_start`)."""
        return [self.warm_start(ctx, sig)]

    def start_on(self, structure: Any, theta: np.ndarray, data: Any) -> np.ndarray | None:
        """Effect parameters to start ``rigd identify --add`` from, on the fitted base
        ``structure`` at ``theta`` (None: :meth:`theta0_effect`)."""
        return None

    def refit_alternatives(self, ctx: Context, sig: SignatureFit) -> list[SignatureFit]:
        """Other forms of the effect the diagnosis refits beside the first (default: none)."""
        return []

    def refit_fixed(self, ext: Any, sig: SignatureFit | None = None) -> list[str]:
        """Parameters of the extended model ``ext`` the diagnosis refit keeps at their start
        (a redundant scale; default: none)."""
        return []

    def evidence(self, ctx: Context, sig: SignatureFit) -> tuple[str, dict] | None:
        """(evidence code, numbers) worded by rigd.diagnose.wording for the record's domain;
        None: the effect words its own explanation (:meth:`explain`)."""
        return None

    def refitted_evidence(self, ctx: Context, theta_e: np.ndarray) -> dict:
        """Numbers read better from the refit than from the signature (a delay's size;
        default: none)."""
        return {}


def is_mechanical(structure: Any) -> bool:
    """True for a mechanical base (x = [p, ṗ]) whose simulator takes the state feedback
    (rigd.ident.greybox.mechanical and the modal structures built on it; ``Model.carries``),
    with effects composed around it or not. A general LTI model's states are modal: not
    mechanical."""
    return "mechanical" in carries(structure)


def dims(base: Any) -> tuple[int, int]:
    """(ny, nu) of a model (``Model.ny`` / ``Model.nu``)."""
    return int(base.ny), int(base.nu)
