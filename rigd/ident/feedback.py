"""The Lur'e feedback block of a mechanical base: what state-level effects feed back.

A mechanical base p̈ + D ṗ + K p = B u (states x = [p, ṗ], ``rigd.ident.greybox.mechanical``) carries
state-level effects as a feedback w = φ(C_f x) into its force input (Lur'e form):

    p̈ + (D + ΔD) ṗ + (K + ΔK) p + k₃∘p³ + k₃ᶜ∘(|p|² − p²)∘p + F_c∘tanh(ṗ / v_ε) = (B + ΔB) u

* ΔK, ΔD, ΔB (``dK``, ``dD``, ``dB``): a linear φ, folded into the matrices (cross coupling);
* ``k3``, ``k3_cross``: a memoryless cubic φ (film stiffening; RK4 in the compiled kernel);
* ``friction`` (2, m): Coulomb sizes F_c and smoothing velocities v_ε (RK4 with sub-steps).

Each state-level effect returns one :class:`MechanicalFeedback` (``Effect.state_block``); the
composition (``rigd.effects.compose``) sums them (:meth:`MechanicalFeedback.plus`) and hands
the sum to the base's simulator. Units: mass-normalised (accelerations per output unit).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

__all__ = ["MechanicalFeedback"]


def _add(a, b):
    if a is None:
        return b
    if b is None:
        return a
    return np.asarray(a, float) + np.asarray(b, float)


@dataclass(frozen=True)
class MechanicalFeedback:
    """State feedback into a mechanical base (module docstring).

    Attributes
    ----------
    dK, dD : ndarray (m, m), optional
        Added to K (1/s²) and D (1/s).
    dB : ndarray (m, nu), optional
        Added to B (output unit / s² per input unit).
    k3, k3_cross : ndarray (m,), optional
        Per-axis cubic stiffness k3_i p_i³ and cross term k3_cross_i (Σ_{j≠i} p_j²) p_i
        (1 / (output unit² s²)).
    friction : ndarray (2, m), optional
        Row 0: Coulomb force per axis (acceleration units), row 1: smoothing velocity
        (output units/s). At most one friction block per model.
    """

    dK: np.ndarray | None = None
    dD: np.ndarray | None = None
    dB: np.ndarray | None = None
    k3: np.ndarray | None = None
    k3_cross: np.ndarray | None = None
    friction: np.ndarray | None = None

    def plus(self, other: MechanicalFeedback | None) -> MechanicalFeedback:
        """The sum of two feedback blocks (both act on the same base at once).

        Raises
        ------
        ValueError
            If both carry friction (one Coulomb term per axis).
        """
        if other is None:
            return self
        if self.friction is not None and other.friction is not None:
            raise ValueError("friction added twice")
        return MechanicalFeedback(**{f.name: (_add(getattr(self, f.name), getattr(other, f.name))
                                              if f.name != "friction" else
                                              (self.friction if other.friction is None
                                               else other.friction))
                                     for f in fields(self)})

    def as_dict(self) -> dict[str, np.ndarray | None]:
        """Field name -> value (None where unset)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
