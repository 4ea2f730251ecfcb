"""Physical effects a grey-box model may leave out: one module per effect, one registry.

``REGISTRY`` maps each canonical name (``../shared/DESIGN.md``) to an :class:`Effect`
instance. A new effect is one new module with an :class:`Effect` subclass, registered below::

    from rigd.effects import REGISTRY, extend
    REGISTRY["cubic_stiffness"].extend(structure)     # one effect
    extend(structure, ["delay", "runout"])            # several (state-level ones first)
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rigd.effects.actuator_dynamics import ActuatorDynamics
from rigd.effects.base import Effect
from rigd.effects.compose import Composed
from rigd.effects.context import CannotReveal, Context, Finding
from rigd.effects.creep import Creep
from rigd.effects.cross_coupling import CrossCoupling
from rigd.effects.cubic_stiffness import CubicStiffness
from rigd.effects.delay import Delay
from rigd.effects.extra_dynamics import ExtraDynamics
from rigd.effects.extra_mode import ExtraMode
from rigd.effects.friction import Friction
from rigd.effects.hysteresis import Hysteresis
from rigd.effects.integrator import Integrator
from rigd.effects.mode_site import mode_effects
from rigd.effects.restoring_hysteresis import RestoringHysteresis
from rigd.effects.runout import Runout
from rigd.effects.static_nonlinearity import StaticNonlinearity
from rigd.errors import InputError

#: canonical name -> effect (the one place a new effect is registered)
REGISTRY: dict[str, Effect] = {e.name: e for e in (
    Runout(), Delay(), ActuatorDynamics(), Hysteresis(), Creep(), CubicStiffness(),
    ExtraMode(), CrossCoupling(), RestoringHysteresis(),
    # domain-neutral entries (generic records): ../shared/DESIGN.md
    StaticNonlinearity(), Friction(), Integrator(), ExtraDynamics(),
    # restoring forces on one mode of a modal LTI base (the ``mode`` site)
    *mode_effects(),
)}

_ORDER = {"state": 0, "input": 1, "output": 2}


def resolve(names: Iterable[str], where: str | None = None) -> list[Effect]:
    """The registered effects ``names``, in order (the one unknown-effect check).

    Used for ``--add`` / ``--effects`` on the command line and to rebuild the effects a model
    file names (``rigd.ident.modelfile.load_model(path, resolve_effects=resolve)``).

    Raises
    ------
    InputError
        Naming the unknown names (at ``where``) and listing the known ones, or a name given
        twice.
    """
    names = list(names)
    unknown = [n for n in names if n not in REGISTRY]
    if unknown:
        raise InputError(f"unknown effect(s) {', '.join(unknown)} (known: "
                         f"{', '.join(sorted(REGISTRY))})", where)
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:  # its parameters would appear twice under the same names
        raise InputError(f"effect(s) {', '.join(dup)} given more than once", where)
    return [REGISTRY[n] for n in names]


def get(name: str) -> Effect:
    """The registered effect ``name``; InputError listing the known names otherwise."""
    return resolve([name])[0]


def extend(structure: Any, names: Iterable[str]) -> Any:
    """``structure`` extended by several effects: one :class:`Composed` (added state-level
    first, then input-, then output-level, in the given order within a site: the order of
    their parameters and of a model file's ``effects``)."""
    effects = sorted(resolve(names), key=lambda e: _ORDER.get(e.sites[0] if e.sites else "", 1))
    for e in effects:
        structure = e.extend(structure)
    return structure


__all__ = ["REGISTRY", "Effect", "Finding", "CannotReveal", "Context", "Composed",
           "get", "resolve", "extend"]
