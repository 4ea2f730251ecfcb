"""The record's domain: which words and which advice fit it.

rigd diagnoses records of its own rotor rig and records from any lab. What is said about a
finding (a "film" or a "valve", a "resonance" or a "time constant", a rotor experiment file
or a step held for a few time constants) depends on what the record is, decided here once
per sub-model and used by :mod:`rigd.diagnose.wording` and :mod:`rigd.diagnose.advice`:

* ``rotor`` — a rotor rig sub-model (``actuator`` r→u, ``bearing`` u→e: the rig's known
  channel names), or a record whose ``source`` metadata (``simulated`` / ``rig``) says
  rigd's recorder wrote it;
* ``mechanical`` — any other record whose base model has a lightly damped complex pole pair
  (ζ < :data:`LIGHT_DAMPING`): a structure with modes and resonances;
* ``process`` — a base model with real poles or heavily damped ones only (thermal,
  chemical, level, flow plants): time constants, no resonance, no stiffness;
* ``generic`` — no linear part to read poles from: neutral words.

An effect declares the domains its physics belongs to (``Effect.domains``: a stiffness or a
restoring force for rotor, mechanical and generic records, a shaft's run-out where parts may
rotate); one of another domain is not offered (:func:`offered`). What the *base model* must
carry (``Effect.requires``: velocity states for ``friction``) is a separate question,
answered by ``Effect.not_offered(structure)``: friction is domain-neutral (a positioning
stage, a sticking control valve) but needs a base with velocities.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: damping ratio below which a complex pole pair makes the record mechanical (a resonance
#: stands out of the response: peak gain ≈ 1/(2ζ) ≥ 1.7)
LIGHT_DAMPING = 0.3

DOMAINS = ("rotor", "mechanical", "process", "generic")

@dataclass(frozen=True)
class Domain:
    """The domain of one sub-model and why (one line for the notes)."""

    name: str
    why: str

    @property
    def rotor(self) -> bool:
        return self.name == "rotor"

    def to_json(self) -> dict[str, Any]:
        return {"domain": self.name, "why": self.why}


def _poles(structure: Any, theta: np.ndarray) -> np.ndarray | None:
    """Continuous-time poles of the base's linear part (None: none readable,
    :func:`rigd.ident.model.linear_part_of`)."""
    from rigd.ident.model import linear_part_of

    lp = linear_part_of(structure, theta)
    return None if lp is None else np.linalg.eigvals(np.asarray(lp.A, float))


def decide(submodel: str, meta: dict[str, Any], structure: Any = None,
           theta: np.ndarray | None = None) -> Domain:
    """The domain of ``submodel`` of a record with metadata ``meta`` whose base model is
    ``structure`` at ``theta`` (module docstring)."""
    if submodel in ("actuator", "bearing"):
        return Domain("rotor", f"the rotor rig's {submodel} sub-model (its channels)")
    src = (meta or {}).get("source")
    if src in ("simulated", "rig"):  # rigd's recorder states it (rigd.api.data.SOURCES)
        return Domain("rotor", f"written by rigd's recorder (source: {src})")
    lam = None if structure is None or theta is None else _poles(structure, theta)
    if lam is None or lam.size == 0:
        return Domain("generic", "no linear part to read poles from")
    cplx = lam[np.abs(lam.imag) > 1e-12]
    zeta = -cplx.real / np.maximum(np.abs(cplx), 1e-300)
    if cplx.size and float(np.min(zeta)) < LIGHT_DAMPING:
        f = float(np.abs(cplx[int(np.argmin(zeta))]) / (2 * np.pi))
        return Domain("mechanical", f"a lightly damped pole pair (ζ = {float(np.min(zeta)):.3g} "
                      f"at {f:.4g} Hz)")
    return Domain("process", "real or heavily damped poles only (ζ ≥ "
                  f"{LIGHT_DAMPING:g}): a process of time constants")


def offered(effect: Any, domain: Domain) -> bool:
    """True when ``effect`` (an :class:`rigd.effects.base.Effect`) applies to the domain:
    ``effect.domains`` (None: every domain) names it. What the base must carry
    (``effect.requires``) is the base's question (``Effect.not_offered``), not the domain's."""
    doms = effect.domains
    return doms is None or domain.name in doms


def time_constants(structure: Any, theta: np.ndarray) -> list[float]:
    """Time constants (s) of the base's poles, 1/|Re p|, slowest first (an integrator or
    an unreadable linear part gives none)."""
    lam = _poles(structure, theta)
    if lam is None:
        return []
    re = np.abs(lam.real)
    return sorted({float(1.0 / v) for v in re if v > 1e-12}, reverse=True)
