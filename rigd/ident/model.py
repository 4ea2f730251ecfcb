"""The one interface every model family satisfies: :class:`Model` and its :class:`LinearPart`.

A *model family* (the general LTI state-space model :mod:`rigd.ident.lti.statespace`, the
low-order process model :mod:`rigd.ident.lti.process`, the grey-box rotor and mechanical
structures of :mod:`rigd.ident.greybox`) is a parametrised model class 𝔐(θ). The fitter
(:func:`rigd.ident.pem.fit`), the workflow, the effects, compare and the model files use only
what :class:`Model` lists:

* ``names`` — the parameter names (θ's order); ``x0_index`` / ``offset_index`` — the entries
  of θ that are the initial state and constant output offsets (re-estimated on a new record
  by :func:`rigd.ident.workflow.estimate_x0`); ``noise_index`` — entries used only by the
  one-step predictor (frozen by an output-error fit);
* ``theta0(data)``, ``bounds()``, ``scale(theta)`` — start values, bounds and typical sizes;
* ``simulate(theta, data)`` — the simulated output (n, ny); optional ``predict(theta,
  data)`` (one-step-ahead, for PEM; ``None`` if unstable); a mechanical base takes a third
  argument, the state-level effects' ``feedback`` (rigd.ident.feedback);
* ``linear_part(theta)`` — the model's linear dynamics as a :class:`LinearPart`. Every
  read-out (poles, f_n/ζ, time constants, integrators, the static gain of the *whole* model)
  is computed from it in one place, :mod:`rigd.ident.readouts`;
* ``readouts(theta)`` and ``spec()`` — what the model file stores.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.ident.iddata import IdData

HOLDS = ("zoh", "foh")


@dataclass(frozen=True)
class LinearPart:
    """The linear dynamics of a model: ẋ = A x + B u(t − τ), y = C x + D u(t − τ).

    Attributes
    ----------
    A : ndarray (nx, nx)
        Continuous state matrix, 1/s.
    B : ndarray (nx, nu)
        Continuous input matrix (state units per input unit per second).
    C : ndarray (ny, nx)
        Output matrix.
    D : ndarray (ny, nu)
        Feedthrough (output units per input unit).
    K : ndarray (nx, ny) or None
        Innovation (disturbance) gain of the one-step predictor, discrete, when the family
        has one.
    delays : tuple of int
        Per-input transport delay τ_j, in samples (``u_j[k − τ_j]`` drives the model).
    hold : {"zoh", "foh"}
        Input between samples: held, or linear.
    input_names, output_names : tuple of str
    fs : float or None
        Sample rate, Hz (the delays in seconds are ``delays / fs``).
    integrators : tuple of int
        States that are explicit integrators (their pole sits at 0 by construction).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    K: np.ndarray | None = None
    delays: tuple[int, ...] = ()
    hold: str = "zoh"
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    fs: float | None = None
    integrators: tuple[int, ...] = field(default_factory=tuple)

    def __post_init__(self):
        if self.hold not in HOLDS:
            raise ValueError(f"hold must be 'zoh' or 'foh', got {self.hold!r}")
        nu = np.asarray(self.B).shape[1]
        if not self.delays:
            object.__setattr__(self, "delays", (0,) * nu)
        if len(self.delays) != nu:
            raise ValueError(f"{len(self.delays)} delays for {nu} inputs")

    @property
    def nx(self) -> int:
        return int(np.asarray(self.A).shape[0])

    @property
    def nu(self) -> int:
        return int(np.asarray(self.B).shape[1])

    @property
    def ny(self) -> int:
        return int(np.asarray(self.C).shape[0])

    def ss(self, name: str = "model"):
        """The delay-free part as a continuous python-control ``StateSpace``."""
        import control

        kw = {}
        if len(self.input_names) == self.nu and len(self.output_names) == self.ny:
            kw = {"inputs": list(self.input_names), "outputs": list(self.output_names)}
        return control.ss(self.A, self.B, self.C, self.D, name=name, **kw)


class Model:
    """Base class of every model family (module docstring): a parametrised model 𝔐(θ).

    Subclasses set ``kind`` (the model-file name) and ``names`` and implement ``theta0``,
    ``simulate`` and, where the family has them, ``predict``, ``ss``, ``linear_part`` and
    ``readouts``. The defaults below are what a family without the feature means (no
    bounds, no typical sizes, nothing to bind to the record, no read-outs, no output
    offsets), so that callers ask the model instead of probing for attributes. A base with
    effects composed around it (:class:`rigd.effects.compose.Composed`) is a Model too; its
    ``effect_list`` names them (empty here) and ``base`` is the model under them.
    """

    kind: str = "model"
    names: list[str] = []
    #: the channels (set by every family; a composed model reads its base's)
    input_names: list[str]
    output_names: list[str]
    nu: int
    ny: int
    #: indices into theta of the initial-state parameters (re-estimated on new data)
    x0_index: list[int] = []
    #: indices into theta of constant output offsets (re-estimated on new data like x0)
    offset_index: list[int] = []
    #: indices into theta used only by the one-step predictor (frozen by an OE fit)
    noise_index: list[int] = []
    #: names of the effects composed into the model (empty for a base model)
    effects: list[str] = []
    #: the effects composed around :attr:`base` (empty for a base model)
    effect_list: tuple = ()
    #: the model under the effects (None: this is a base model)
    base: Model | None = None
    #: what the model can carry for an effect (rigd.effects.compose.REQUIREMENTS):
    #: ``mechanical`` (states [p, ṗ] and a simulator that takes state feedback), ``mode``
    #: (modal complex-pair blocks); ``rotation`` is the record's, not the model's
    carries: frozenset[str] = frozenset()
    #: per-input transport delays, samples (empty: none)
    delays: tuple[int, ...] = ()
    #: the inputs between samples: ``zoh`` (held) or ``foh`` (linear)
    hold: str = "zoh"
    #: indices into theta of initial velocities (a mechanical model's; empty otherwise)
    velocity_index: list[int] = []
    #: the output is ``(…) + y_off`` whatever the other parameters (the offsets' Jacobian
    #: columns are ones: rigd.ident.jacobian.additive_offsets)
    additive_offsets: bool = False
    #: ``output_sensitivities(theta, data) -> (indices, dY)``: the exact ∂ŷ/∂θ of the
    #: parameters the output is linear in (rigd.ident.jacobian); None: the family has none
    output_sensitivities = None
    #: samples of the estimation record the model was laid out for (``set_record``)
    _n_est: int | None = None

    @property
    def npar(self) -> int:
        return len(self.names)

    @property
    def n_integrators(self) -> int:
        """Explicit integrators (poles at 0 by construction) in the model."""
        return 0

    @property
    def n_parallel_modes(self) -> int:
        """Modes in parallel with the base dynamics (the mechanical model's beyond one per
        output: rigd.ident.greybox.parallel)."""
        return 0

    @property
    def fixed_names(self) -> list[str]:
        """Parameters no fit moves (default: none; a composed model's effects state theirs)."""
        return []

    def theta0(self, data: IdData) -> np.ndarray:
        """Automatic start values on ``data`` (the estimation part)."""
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper parameter bounds (default: unbounded)."""
        return np.full(self.npar, -np.inf), np.full(self.npar, np.inf)

    def scale(self, theta: np.ndarray) -> np.ndarray:
        """Typical magnitude of each parameter (for step sizes and scaling of the fit)."""
        return np.maximum(np.abs(theta), 1e-6)

    def typical(self) -> np.ndarray | None:
        """Typical sizes of parameters that :meth:`scale` cannot judge from their value
        (None: none; :class:`rigd.effects.compose.Composed` states its effects')."""
        return None

    def bind_record(self, data: IdData) -> None:
        """Make record-relative bounds refer to ``data`` (the estimation data; default:
        nothing depends on the record)."""

    def simulate(self, theta: np.ndarray, data: IdData) -> np.ndarray:
        """Simulated output (n, ny) from the inputs of ``data`` alone."""
        raise NotImplementedError

    def predict(self, theta: np.ndarray, data: IdData) -> np.ndarray | None:
        """One-step-ahead prediction; ``None`` if the predictor is unstable at theta."""
        raise NotImplementedError(f"{self.kind} has no one-step predictor")

    def ss(self, theta: np.ndarray):
        """The (linear part of the) model as a continuous python-control StateSpace."""
        raise NotImplementedError(f"{self.kind} has no linear state-space form")

    def continuous(self, theta: np.ndarray):
        """(A, B, C, D, x0): the continuous state-space form at ``theta``."""
        raise NotImplementedError(f"{self.kind} has no continuous state-space form")

    def linear_part(self, theta: np.ndarray) -> LinearPart:
        """The model's linear dynamics at ``theta``."""
        raise NotImplementedError(f"{self.kind} has no linear part")

    def linear_ss(self, theta: np.ndarray, fs: float, G0: Any = None):
        """(G, included, left_out): the model as a linear design model — :meth:`ss` (or
        ``G0`` in its place), no effect blocks (a composed model adds its effects' small-
        signal blocks: :meth:`rigd.effects.compose.Composed.linear_ss`)."""
        return (self.ss(theta) if G0 is None else G0), [], {}

    def output_offset(self, theta: np.ndarray) -> np.ndarray | None:
        """Constant output offsets (ny,) at ``theta``, None when the family has none."""
        return None

    def readouts(self, theta: np.ndarray) -> dict[str, Any]:
        """Read-outs stored in the model file (:func:`rigd.ident.readouts.linear_readouts`)."""
        return {}

    def spec(self) -> dict[str, Any]:
        """What a model file stores to rebuild the model (rigd.ident.modelfile)."""
        return {"kind": self.kind}

    def describe(self) -> str:
        """Its size in words for the terminal and the report ("3 modes, 1 real pole");
        empty: the caller counts its states."""
        return ""

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, theta)}


def base_of(structure: Any) -> Any:
    """The base model under its effects (``structure`` itself for a base model; a
    :class:`rigd.effects.compose.Composed` has its ``base``, never itself composed)."""
    return structure if structure.base is None else structure.base


def linear_part_of(structure: Any, theta: np.ndarray) -> LinearPart | None:
    """:class:`LinearPart` of ``structure`` (or of its base under effect wrappers) at
    ``theta``; None if it has none or it cannot be formed at ``theta``."""
    base = base_of(structure)
    th = np.asarray(theta, float)[:len(base.names)]
    try:
        return base.linear_part(th)
    except (NotImplementedError, ValueError, np.linalg.LinAlgError, FloatingPointError):
        return None
