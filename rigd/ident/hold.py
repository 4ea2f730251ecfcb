"""How a record's inputs behave between samples, and how it is chosen (MATLAB ``InterSample``).

A sampled input u[k] stands either for a signal *held* over the sample period (zero-order
hold, ``"zoh"``: the commanded references r a DAC or the loop puts out) or for a smooth signal
that was *measured* (first-order hold, ``"foh"``: linear between samples — valve positions,
another rig's force or voltage sensor). Simulating a model with the wrong hold shifts its
input by about half a sample (T/2 = 0.1 ms at 5 kHz), which a fit reads as a fast phase lag
and a diagnosis as a spurious ``delay``. MATLAB's ``iddata`` carries the same property as
``InterSample``.

Resolution, the same for ``rigd identify`` and ``rigd diagnose`` (one convention):

1. asked for on the command line (``--hold zoh|foh``);
2. declared by the record: metadata ``intersample: zoh`` (all inputs) or a mapping
   ``intersample: {r_x: zoh, r_y: zoh, u_x: foh, u_y: foh}`` (the sub-model's inputs must agree);
3. a rigd recording (metadata ``rigd_version``, kept by ``rigd export``): the physics is known,
   :data:`rigd.ident.mechanical.DEFAULT_HOLD` (references ZOH, measured positions FOH);
4. otherwise — data this project did not make — chosen from the data: the base model is
   fitted by output error on the estimation part with each hold, and the hold with the better
   fit is kept; the sub-model's default wins unless the other is better by
   :data:`MARGIN_POINTS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.errors import InputError
from rigd.ident.iddata import IdData
from rigd.ident.mechanical import DEFAULT_HOLD, structure_for
from rigd.ident.thresholds import HOLD_MARGIN_POINTS

HOLDS = ("zoh", "foh")

#: Fit points (100·(1 − NRMSE)) by which the non-default hold must win to be chosen.
MARGIN_POINTS = HOLD_MARGIN_POINTS


@dataclass(frozen=True)
class HoldChoice:
    """The input hold used for a sub-model and why.

    Attributes
    ----------
    hold : {"zoh", "foh"}
    source : {"asked", "declared", "rigd recording", "fit"}
    fits : dict of str -> float
        Estimation-part OE fit (%) per hold, when chosen from the data.
    """

    hold: str
    source: str
    fits: dict[str, float] = field(default_factory=dict)

    def describe(self) -> str:
        """One line for people, e.g. ``foh (chosen from the data: foh 99.48 %, zoh 94.52 %)``."""
        words = {"zoh": "held over each sample", "foh": "linear between samples"}[self.hold]
        if self.source == "fit":
            alt = ", ".join(f"{h} {f:.2f} %" for h, f in self.fits.items())
            return f"{self.hold} ({words}; chosen from the data: OE fit {alt})"
        return f"{self.hold} ({words}; {self.source})"

    def as_dict(self) -> dict[str, Any]:
        """JSON/YAML form for the model file and ``--json``."""
        out: dict[str, Any] = {"hold": self.hold, "source": self.source}
        if self.fits:
            out["fits"] = {h: round(float(f), 3) for h, f in self.fits.items()}
        return out


def declared_hold(meta: dict[str, Any], inputs: list[str], where: str) -> str | None:
    """The hold the record declares for ``inputs`` (metadata ``intersample``), or None.

    Raises
    ------
    InputError
        A value other than zoh/foh, a mapping without one of ``inputs``, or inputs that
        disagree.
    """
    v = meta.get("intersample")
    if v is None:
        return None
    if isinstance(v, str):
        per = {name: v for name in inputs}
    elif isinstance(v, dict):
        missing = [name for name in inputs if name not in v]
        if missing:
            raise InputError(f"metadata intersample: no entry for input(s) "
                             f"{', '.join(missing)} (has: {', '.join(map(str, v))})", where)
        per = {name: v[name] for name in inputs}
    else:
        raise InputError(f"metadata intersample must be zoh, foh or a mapping channel -> "
                         f"zoh|foh, got {v!r}", where)
    bad = {k: h for k, h in per.items() if str(h).lower() not in HOLDS}
    if bad:
        k, h = next(iter(bad.items()))
        raise InputError(f"metadata intersample: {k}: {h!r} is not zoh or foh", where)
    holds = {str(h).lower() for h in per.values()}
    if len(holds) > 1:
        raise InputError(f"metadata intersample: the inputs {', '.join(inputs)} of one model "
                         f"must share one hold, got {per}", where)
    return holds.pop() if holds else None


def choose_hold(submodel: str, est: IdData, meta: dict[str, Any], asked: str | None = None,
                *, where: str = "<record>") -> HoldChoice:
    """The input hold for ``submodel`` (see the module docstring for the order).

    Parameters
    ----------
    submodel : {"actuator", "bearing", "generic"}
    est : IdData
        Prefiltered estimation data of the sub-model (used only when chosen from the data).
    meta : dict
        The record's metadata.
    asked : {"zoh", "foh", "auto", None}
        From the command line; ``"auto"``/None = not asked.
    where : str
        The record's path, for error messages.
    """
    if asked not in (None, "auto"):
        if asked not in HOLDS:
            raise InputError(f"--hold must be zoh, foh or auto, got {asked!r}")
        return HoldChoice(asked, "asked")
    declared = declared_hold(meta, list(est.input_names), where)
    if declared is not None:
        return HoldChoice(declared, "declared")
    default = DEFAULT_HOLD.get(submodel, "zoh")
    if meta.get("rigd_version") is not None:
        return HoldChoice(default, "rigd recording")
    from rigd.ident.pem import fit, fit_percent

    fits: dict[str, float] = {}
    for h in (default, "zoh" if default == "foh" else "foh"):
        s = structure_for(submodel, est, hold=h)
        res = fit(s, est, method="oe")
        fits[h] = float(np.mean(fit_percent(est.y, np.asarray(s.simulate(res.theta, est)))))
    other = next(h for h in fits if h != default)
    best = other if fits[other] > fits[default] + MARGIN_POINTS else default
    return HoldChoice(best, "fit", fits)
