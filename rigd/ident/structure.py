"""Grey-box model structures: named parameters that simulate (and predict) an :class:`IdData`.

A *structure* is the model class 𝔐(θ) of the paper (Eqs. 7 and 9): it knows its parameter
``names``, an automatic initial guess ``theta0(data)``, ``bounds()``, ``simulate(theta, data)``
(output error) and, where defined, ``predict(theta, data)`` (one-step-ahead, for PEM).

Physical effects (``rigd.effects``) extend a structure without touching it
(``Effect.extend``, rigd.effects.compose: input blocks before the base, output blocks after
it, a mechanical base's state feedback, :class:`~rigd.ident.feedback.MechanicalFeedback`,
into its simulator).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.ident.iddata import IdData


class Structure:
    """Base class of grey-box structures (see module docstring).

    Subclasses set ``kind`` (model-file name), ``names`` and implement ``theta0``,
    ``simulate``, optionally ``predict``, ``ss`` and ``readouts``.
    """

    kind: str = "structure"
    names: list[str] = []
    #: indices into theta of the initial-state parameters (re-estimated on new data)
    x0_index: list[int] = []
    #: indices into theta of constant output offsets (re-estimated on new data like x0)
    offset_index: list[int] = []
    #: indices into theta used only by the one-step predictor (frozen by an OE fit)
    noise_index: list[int] = []
    #: names of the extensions applied (empty for a base structure)
    effects: list[str] = []

    @property
    def npar(self) -> int:
        return len(self.names)

    def theta0(self, data: IdData) -> np.ndarray:
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper parameter bounds (default: unbounded)."""
        return np.full(self.npar, -np.inf), np.full(self.npar, np.inf)

    def scale(self, theta: np.ndarray) -> np.ndarray:
        """Typical magnitude of each parameter (for step sizes and scaling of the fit)."""
        return np.maximum(np.abs(theta), 1e-6)

    def simulate(self, theta: np.ndarray, data: IdData) -> np.ndarray:
        raise NotImplementedError

    def predict(self, theta: np.ndarray, data: IdData) -> np.ndarray | None:
        """One-step-ahead prediction; ``None`` if the predictor is unstable at theta."""
        raise NotImplementedError(f"{self.kind} has no one-step predictor")

    def ss(self, theta: np.ndarray):
        """The (linear part of the) model as a continuous python-control StateSpace."""
        raise NotImplementedError

    def linear_part(self, theta: np.ndarray):
        """The model's linear dynamics, a :class:`rigd.ident.model.LinearPart`."""
        raise NotImplementedError

    def readouts(self, theta: np.ndarray) -> dict[str, Any]:
        """Physical read-outs (natural frequencies, damping ratios, gains)."""
        return {}

    def spec(self) -> dict[str, Any]:
        """What a model file stores to rebuild this structure (see modelfile.py)."""
        return {"kind": self.kind}

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, theta)}
