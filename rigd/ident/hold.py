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
   :data:`rigd.ident.greybox.submodels.DEFAULT_HOLD` (references ZOH, measured positions FOH);
4. otherwise — data this project did not make — chosen from the data: the base model is
   fitted by output error on the estimation part with each hold, and the hold with the better
   fit is kept; the sub-model's default wins unless the other is better by
   :data:`MARGIN_POINTS`. A generic record whose first response comes two or more samples
   after the input (a transport delay, or a chain's relative degree) is compared per hold
   with the better of the model without and with that hold's reading of the delay
   (:func:`_hold_fit`) — without it, ZOH's half-sample lag stands in for part of a transport
   delay and wins on data whose inputs were linear between samples; with it alone, a long
   lag that is no delay (a 3-mass chain's 32 samples) would shift the input and decide.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.errors import InputError
from rigd.ident.greybox.submodels import DEFAULT_HOLD, structure_for
from rigd.ident.iddata import IdData
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
    lags = _response_lags(submodel, est)
    fits: dict[str, float] = {}
    for h in (default, "zoh" if default == "foh" else "foh"):
        fits[h] = _hold_fit(submodel, est, h, lags)
    other = next(h for h in fits if h != default)
    best = other if fits[other] > fits[default] + MARGIN_POINTS else default
    return HoldChoice(best, "fit", fits)


def _response_lags(submodel: str, est: IdData) -> list[int] | None:
    """Per-input lag (samples) of the first response of a generic record
    (:func:`rigd.ident.lti.delay.estimate_delays`), or None when no input's response comes
    later than the hold's own sample (lag ≤ 1: no transport delay to carry)."""
    if submodel != "generic":
        return None
    from rigd.ident.lti.delay import estimate_delays

    nk = [int(e.nk) for e in estimate_delays(np.asarray(est.u, float),
                                             np.asarray(est.y, float))]
    return nk if max(nk + [0]) >= 2 else None


def _shifted(est: IdData, d: list[int]) -> IdData:
    """``est`` with input j delayed by ``d[j]`` samples (its first value held before)."""
    u = np.asarray(est.u, float)
    us = np.column_stack([np.r_[np.full(k, u[0, j]), u[:u.shape[0] - k, j]]
                          for j, k in enumerate(d)])
    return IdData(us, est.y, est.fs, list(est.input_names), list(est.output_names))


def _hold_fit(submodel: str, est: IdData, hold: str, lags: list[int] | None) -> float:
    """Estimation-part OE fit (%) of the sub-model's base structure with input ``hold``.

    With ``lags`` (a first response two or more samples late, :func:`_response_lags`) the
    fit counted is the best of the model without a delay and with the inputs delayed as the
    hold reads that lag (ZOH: nk − 1 samples, FOH: nk) and by one sample either way, all
    measured on the same samples (after the longest shift). The delay-free fit keeps a lag
    that is no transport delay (a chain's relative degree) from deciding; the delayed ones
    keep ZOH's half-sample lag from standing in for part of a real delay."""
    from rigd.ident.pem import fit, fit_percent

    s = structure_for(submodel, est, hold=hold)
    if lags is None:
        res = fit(s, est, method="oe")
        return float(np.mean(fit_percent(est.y, np.asarray(s.simulate(res.theta, est)))))
    base = [max(k - 1, 0) if hold == "zoh" else k for k in lags]
    shifts = [[0] * len(base)] + [[max(b + step, 0) for b in base] for step in (-1, 0, 1)]
    tail = max(max(d) for d in shifts)
    best = -np.inf
    for d in shifts:
        data = _shifted(est, d) if any(d) else est
        try:
            res = fit(s, data, method="oe", skip=max(d))
        except (np.linalg.LinAlgError, ValueError):
            continue
        yh = np.asarray(s.simulate(res.theta, data))
        if np.all(np.isfinite(yh[tail:])):
            best = max(best, float(np.mean(fit_percent(est.y[tail:], yh[tail:]))))
    return best
