"""The base structure of each sub-model of ``rigd identify``: the rotor's actuator and
bearing (:mod:`rigd.ident.greybox.rotor`), the generic n-DOF model of other rigs' records
(:mod:`rigd.ident.greybox.mechanical`), and the input hold each is identified with."""

from __future__ import annotations

from rigd.ident.greybox.mechanical import generic_structure
from rigd.ident.greybox.rotor import actuator_structure, bearing_structure
from rigd.ident.iddata import IdData

#: Input hold per sub-model used by ``rigd identify``: commanded references are held (ZOH),
#: measured signals (valve positions, other rigs' inputs) are linear between samples (FOH).
DEFAULT_HOLD = {"actuator": "zoh", "bearing": "foh", "generic": "foh"}


def structure_for(submodel: str, data: IdData | None = None, spec: dict | None = None,
                  hold: str | None = None):
    """Base structure of a sub-model (``actuator``, ``bearing``, ``generic``).

    ``hold``: ``"zoh"``/``"foh"``; default: the spec's (model files), else ``"zoh"`` (pass
    ``DEFAULT_HOLD[submodel]`` for what ``rigd identify`` uses).
    """
    hold = hold or (spec or {}).get("hold") or "zoh"
    if submodel == "actuator":
        return actuator_structure(hold)
    if submodel == "bearing":
        return bearing_structure(hold)
    if submodel == "generic":
        if spec is not None:
            return generic_structure(list(spec["inputs"]), list(spec["outputs"]), hold,
                                     bool(spec.get("output_offsets", False)))
        return generic_structure(data.input_names, data.output_names, hold)
    raise ValueError(f"unknown sub-model {submodel!r}")
