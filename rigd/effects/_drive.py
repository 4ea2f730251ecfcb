"""Where the valve effects act: the PD drive voltages of the valve pair of each axis.

Hysteresis and creep act on each valve's drive v_i, inside its PD loop
(v = kff·r_p + kp·(r_p − y_p) + kd·ė, docs/loop.md), not on the lumped reference r. A record
of the rig carries the drives (``v_1``..``v_4``, carried by actuator data as aux channels,
rigd.ident.iddata); Eq. 1 pairs them per axis: x ← (v_2, v_4), y ← (v_1, v_3) (r_p = (r0 + r_y,
r0 + r_x, r0 − r_y, r0 − r_x)). For a closed valve loop whose valve input gets an extra δ_i,
superposition gives u = H_a(s)·(r + (δ_+ − δ_−)/(2·(kff + kp))): the effect enters the
actuator model (r → u, Eqs. 8–10) as an input correction computed from the recorded drives,
the loop's suppression 1/(kff + kp) absorbed in the fitted gain.

Without recorded drives (generic records, an open-loop actuator) the input itself is the
drive.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.effects._signals import spread

#: valve pair (plus, minus) of each lumped axis, Eq. 1 (0-based: v_2, v_4 and v_1, v_3)
AXIS_VALVES = ((1, 3), (0, 2))


def valve_pairs(data: Any) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """[(v_plus, v_minus)] per input axis from the recorded drives, or None."""
    aux = getattr(data, "aux", None) or {}
    u = np.asarray(data.inputs)
    names = list(getattr(data, "input_names", []) or [])
    if u.shape[1] != 2 or names[:2] != ["r_x", "r_y"]:
        return None
    v = [aux.get(f"v_{i + 1}") for i in range(4)]
    if any(x is None or len(x) != u.shape[0] for x in v):
        return None
    return [(np.ascontiguousarray(v[a], dtype=float), np.ascontiguousarray(v[b], dtype=float))
            for a, b in AXIS_VALVES]


def drive_note(data: Any) -> str:
    """How the operator input is taken, for explanations."""
    return ("the recorded valve drives" if valve_pairs(data) is not None
            else "the input")


def drive_spread(data: Any) -> float:
    """Half-amplitude of the drives (the recorded valve drives, else the inputs;
    :func:`rigd.effects._signals.spread`), in their unit (V): the scale of the valve
    effects' operator constants."""
    pairs = valve_pairs(data)
    x = (np.column_stack([w for pm in pairs for w in pm]) if pairs is not None
         else np.asarray(data.inputs, float))
    return float(np.max(spread(x)))
