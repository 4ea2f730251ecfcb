"""Grey-box model structures: named parameters that simulate (and predict) an :class:`IdData`.

A *structure* is the model class 𝔐(θ) of the paper (Eqs. 7 and 9): it knows its parameter
``names``, an automatic initial guess ``theta0(data)``, ``bounds()``, ``simulate(theta, data)``
(output error) and, where defined, ``predict(theta, data)`` (one-step-ahead, for PEM).

Physical effects (``rigd.effects``) extend a structure without touching it: an
:class:`Extension` appends its own named parameters and, given them, edits the
:class:`~rigd.ident.simulate.Hooks` (input delay, cubic stiffness, extra modes, additive
output, input pre-transform, K/D/B increments) that the base structure's simulator applies.
(:class:`HookedStructure` combines a base structure with any number of extensions and is
itself a structure (so it fits, saves and compares like any other). ``rigd.effects`` has
its own ``ExtendedStructure`` (simulation-level); this one keeps the one-step predictor.)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from rigd.ident.iddata import IdData
from rigd.ident.simulate import Hooks


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

    def simulate(self, theta: np.ndarray, data: IdData, hooks: Hooks | None = None) -> np.ndarray:
        raise NotImplementedError

    def predict(self, theta: np.ndarray, data: IdData,
                hooks: Hooks | None = None) -> np.ndarray | None:
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


@runtime_checkable
class Extension(Protocol):
    """What an effect supplies to extend a structure (see ``docs/identify.md``).

    Attributes
    ----------
    name : str
        Canonical effect name (``delay``, ``cubic_stiffness``, ...).
    names : list of str
        Its parameter names (must not collide with the base's).
    """

    name: str
    names: list[str]

    def theta0(self, data: IdData, base: Structure, base_theta: np.ndarray) -> np.ndarray:
        """Initial values of the extension's parameters."""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the extension's parameters."""

    def apply(self, theta: np.ndarray, hooks: Hooks, data: IdData) -> None:
        """Edit ``hooks`` in place for parameter values ``theta`` (its own parameters only)."""


class HookedStructure(Structure):
    """A base structure plus extensions; parameters are ``base.names + ext.names ...``.

    Parameters
    ----------
    base : Structure
        The structure being extended (a base, or another ExtendedStructure).
    extensions : sequence of Extension
        Applied in order to a fresh :class:`Hooks` on every simulation.
    """

    def __init__(self, base: Structure, extensions: Sequence[Extension]):
        while isinstance(base, HookedStructure):  # flatten
            extensions = list(base.extensions) + list(extensions)
            base = base.base
        self.base = base
        self.extensions = list(extensions)
        self.kind = base.kind
        self.names = list(base.names)
        self._slices = []
        for ext in self.extensions:
            clash = set(ext.names) & set(self.names)
            if clash:
                raise ValueError(f"extension {ext.name} reuses parameter names {sorted(clash)}")
            self._slices.append(slice(len(self.names), len(self.names) + len(ext.names)))
            self.names += list(ext.names)
        self.x0_index = list(base.x0_index)
        self.offset_index = list(base.offset_index)
        self.noise_index = list(getattr(base, "noise_index", []))
        self.effects = [e.name for e in self.extensions]

    def split(self, theta: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        theta = np.asarray(theta, float)
        return theta[:self.base.npar], [theta[s] for s in self._slices]

    def hooks(self, theta: np.ndarray, data: IdData, hooks: Hooks | None = None) -> Hooks:
        hooks = hooks or Hooks()
        _, parts = self.split(theta)
        for ext, th in zip(self.extensions, parts):
            ext.apply(th, hooks, data)
        return hooks

    def theta0(self, data: IdData, base_theta: np.ndarray | None = None) -> np.ndarray:
        bt = self.base.theta0(data) if base_theta is None else np.asarray(base_theta, float)
        return np.concatenate([bt] + [np.asarray(e.theta0(data, self.base, bt), float)
                                      for e in self.extensions])

    def bounds(self):
        lo, hi = self.base.bounds()
        for e in self.extensions:
            elo, ehi = e.bounds()
            lo, hi = np.concatenate([lo, elo]), np.concatenate([hi, ehi])
        return lo, hi

    def scale(self, theta):
        th = np.asarray(theta, float)
        sb = self.base.scale(th[:self.base.npar])
        return np.concatenate([sb, np.maximum(np.abs(th[self.base.npar:]), 1e-3)])

    def simulate(self, theta, data, hooks=None):
        bt, _ = self.split(theta)
        return self.base.simulate(bt, data, self.hooks(theta, data, hooks))

    def predict(self, theta, data, hooks=None):
        bt, _ = self.split(theta)
        return self.base.predict(bt, data, self.hooks(theta, data, hooks))

    def ss(self, theta):
        bt, _ = self.split(theta)
        return self.base.ss(bt)

    def linear_part(self, theta):
        bt, _ = self.split(theta)
        return self.base.linear_part(bt)

    def readouts(self, theta):
        bt, parts = self.split(theta)
        out = self.base.readouts(bt)
        for ext, th in zip(self.extensions, parts):
            out.update({n: float(v) for n, v in zip(ext.names, th)})
        return out

    def spec(self):
        d = self.base.spec()
        d["effects"] = list(self.effects)
        return d
