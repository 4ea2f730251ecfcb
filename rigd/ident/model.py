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
from typing import Any, Protocol, runtime_checkable

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


@runtime_checkable
class Model(Protocol):
    """What every model family provides (module docstring)."""

    kind: str
    names: list[str]
    x0_index: list[int]
    offset_index: list[int]

    def theta0(self, data: IdData) -> np.ndarray:
        """Automatic start values on ``data`` (the estimation part)."""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper parameter bounds."""

    def scale(self, theta: np.ndarray) -> np.ndarray:
        """Typical magnitude of each parameter (step sizes and scaling of the fit)."""

    def simulate(self, theta: np.ndarray, data: IdData) -> np.ndarray:
        """Simulated output (n, ny) from the inputs of ``data`` alone."""

    def linear_part(self, theta: np.ndarray) -> LinearPart:
        """The model's linear dynamics at ``theta``."""

    def readouts(self, theta: np.ndarray) -> dict[str, Any]:
        """Read-outs stored in the model file (:func:`rigd.ident.readouts.linear_readouts`)."""

    def spec(self) -> dict[str, Any]:
        """What a model file stores to rebuild the model."""


def base_of(structure: Any) -> Any:
    """The base model under its effects (a ``rigd.effects.compose.Composed`` has an
    ``effect_list`` and its ``base``)."""
    while hasattr(structure, "effect_list"):
        structure = structure.base
    return structure


def linear_part_of(structure: Any, theta: np.ndarray) -> LinearPart | None:
    """:class:`LinearPart` of ``structure`` (or of its base under effect wrappers) at
    ``theta``; None if it has none or it cannot be formed at ``theta``."""
    base = base_of(structure)
    if not callable(getattr(base, "linear_part", None)):
        return None
    th = np.asarray(theta, float)[:len(base.names)]
    try:
        return base.linear_part(th)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        return None
