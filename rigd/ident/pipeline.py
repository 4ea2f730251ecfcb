"""One pipeline for ``rigd identify`` and ``rigd diagnose``: the base model is fitted in one place.

* :func:`fit_base` — a record's sub-model: analysis window, prefilters, estimation/validation
  split, input hold, start values (``--init``), the fit by the asked method and, for generic
  records, the order search. ``identify`` keeps it (plus the asked effects), ``diagnose`` starts
  its forward selection from it: for the same record and :class:`FitSettings` the two base
  models are the same numbers.
* :func:`refit_with` — a fitted structure extended by effects (objects with ``extend``) and
  refitted by the same method on the same estimation part, from one or several starts (the
  lowest estimation cost is kept, never a validation figure). ``identify --add`` runs it once
  with every asked effect, the diagnosis once per candidate effect and step.
* :func:`analysis_window` — the one rule for long records: without ``--est/--val`` a record
  longer than :data:`MAX_SAMPLES` is analysed on its central :data:`MAX_SAMPLES` samples (both
  commands print and store the window; ``--range A:B`` chooses another).

:meth:`FitSettings.to_json` is what both commands print and store as ``base`` (method, window,
split, hold, order asked, start values).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.errors import InputError
from rigd.ident.iddata import channels_for, from_record
from rigd.ident.pem import METHODS as FIT_METHODS
from rigd.ident.prefilter import apply_prefilters

#: fraction of samples used for estimation when no split is given
DEFAULT_SPLIT = 2.0 / 3.0
#: longest stretch analysed (samples) without --est/--val; longer records: the central window
MAX_SAMPLES = 40_000
#: fit method per sub-model for ``method="auto"`` (``rigd identify``'s default): the paper's
#: prediction-error method (Sec. 4) for the rotor's grey-box sub-models; output error for a
#: generic record, whose held-out figure — like every peer tool's (ARX, subspace, NARX) — is
#: a free-run simulation, which output error minimises (and ``rigd diagnose``'s default: its
#: base model is then identify's). On the DaISy CSTR: PEM 86.30 %, OE 87.59 %, ARX 87.75 %.
AUTO_METHOD = {"actuator": "pem", "bearing": "pem", "generic": "oe"}
METHODS = ("auto", *FIT_METHODS)   # rigd.ident.pem.METHODS, plus "auto"


def method_for(method: str, submodel: str) -> str:
    """The fit method used for ``submodel`` when ``method`` is asked ("auto":
    :data:`AUTO_METHOD`); InputError naming ``--method`` for an unknown one."""
    if method not in METHODS:
        raise InputError(f"unknown fit method {method!r} (known: {', '.join(METHODS)})",
                         "--method")
    return AUTO_METHOD.get(submodel, "oe") if method == "auto" else method


@dataclass
class FitSettings:
    """How the base model of a record is fitted (the same for identify and diagnose).

    Attributes
    ----------
    method : {"pem", "oe"}
        Prediction error or output error (base fit and every refit), as resolved by
        :func:`method_for`.
    split : float, optional
        Estimation fraction (default :data:`DEFAULT_SPLIT`); not with ``est``/``val``.
    est, val : slice, optional
        Estimation and validation samples of the record (both or neither).
    hold : {"auto", "zoh", "foh"}
        Inputs between samples (:func:`rigd.ident.hold.choose_hold`).
    order : "auto" or int
        Generic records: states of the base (:func:`rigd.ident.lti.order.choose_base`), or
        modes with ``mechanical``.
    mechanical : bool
        Generic records: keep the mechanical n-DOF base (plus parallel modes,
        :func:`rigd.ident.greybox.order.choose_order`) — for effects that act on a mechanical state
        (``identify --add cubic_stiffness``).
    init : ModelFile, optional
        Start values of the base fit (``--init``).
    options : PrefilterOptions, optional
    runout : Record, optional
        Run-out record (run-out filter).
    max_samples : int or None
        Window rule of :func:`analysis_window` (None: the whole record).
    """

    method: str = "oe"
    split: float | None = None
    est: slice | None = None
    val: slice | None = None
    hold: str = "auto"
    order: str | int = "auto"
    init: Any = None
    options: Any = None
    runout: Any = None
    max_samples: int | None = MAX_SAMPLES
    mechanical: bool = False

    def check(self) -> None:
        """InputError for settings no record can satisfy."""
        if (self.est is None) != (self.val is None):
            raise InputError("give both --est and --val, or neither", "--est/--val")
        frac = self.fraction
        if self.est is None and not 0.2 <= frac <= 0.95:
            raise InputError(f"split must be within 0.2..0.95 (got {frac})", "--split")
        if self.hold not in ("auto", "zoh", "foh"):
            raise InputError(f"hold must be auto, zoh or foh (got {self.hold!r})", "--hold")

    @property
    def fraction(self) -> float:
        return DEFAULT_SPLIT if self.split is None else float(self.split)

    def to_json(self, window: tuple[int, int], n: int) -> dict[str, Any]:
        """The settings as both commands print and store them (``window`` of ``n`` samples)."""
        out: dict[str, Any] = {"method": self.method, "window": [int(window[0]),
                                                                  int(window[1])],
                               "record_samples": int(n), "hold_asked": self.hold,
                               "order_asked": self.order,
                               "start": "model file" if self.init is not None else "automatic"}
        if self.est is None:
            out["split"] = self.fraction
        return out


def analysis_window(n: int, settings: FitSettings) -> tuple[int, int]:
    """Samples (a, b) of an ``n``-sample record that are analysed: the whole record, or its
    central ``settings.max_samples`` when it is longer and no --est/--val is given."""
    m = settings.max_samples
    if settings.est is None and m is not None and n > m:
        a = (n - m) // 2
        return a, a + m
    return 0, n


def parts(n: int, settings: FitSettings) -> tuple[slice, slice]:
    """Estimation and validation slices of an ``n``-sample (windowed) record."""
    if settings.est is None:
        k = int(round(n * settings.fraction))
        return slice(0, k), slice(k, n)
    return tuple(slice(*s.indices(n)[:2]) for s in (settings.est, settings.val))


@dataclass
class BaseFit:
    """The fitted base model of one sub-model (what :func:`fit_base` returns).

    ``data`` is the prefiltered data of the analysed window, ``est``/``val`` slices of it,
    ``window`` the window's samples in the record, ``result`` the fit (rigd.ident.pem.FitResult)
    of ``structure``; ``order`` the order search (generic records), ``hold`` the input-hold
    choice, ``prefilter`` the prefilter report.
    """

    submodel: str
    data: Any
    est: slice
    val: slice
    window: tuple[int, int]
    structure: Any
    result: Any
    hold: Any
    prefilter: dict
    settings: FitSettings
    order: Any = None
    record_samples: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def theta(self) -> np.ndarray:
        return np.asarray(self.result.theta, float)

    @property
    def est_data(self):
        return self.data.slice(self.est.start, self.est.stop)

    def to_json(self) -> dict[str, Any]:
        """Settings, the method actually used, the hold and the order: printed and stored."""
        out = self.settings.to_json(self.window, self.record_samples)
        out["method_used"] = self.result.method
        out["nfev"] = int(self.result.nfev)
        out["hold"] = self.hold.hold
        if self.order is not None:
            out["modes"] = int(self.order.modes)
            for k in ("family", "states", "delays"):
                if hasattr(self.order, k):
                    out[k if k != "delays" else "delays_samples"] = getattr(self.order, k)
        return out


def prepare(record, submodel: str, options=None, runout=None,
            min_samples: int | None = None) -> tuple[Any, dict]:
    """Prefiltered :class:`IdData` of one sub-model and the prefilter report.

    ``min_samples``: fewest samples accepted (default: what identification needs,
    :data:`rigd.ident.iddata.MIN_SAMPLES`; ``compare`` asks only what the model needs).
    """
    ins, outs = channels_for(record, submodel)
    kw = {} if min_samples is None else {"min_samples": min_samples}
    from_record(record, submodel, **kw)  # column / length checks before filtering
    filt, rep = apply_prefilters(record, ins, outs, options, runout)
    return from_record(filt, submodel, **kw), rep


def start_values(structure, init, submodel: str, data) -> np.ndarray | None:
    """Start values for ``structure`` from a previous model file's parameters of
    ``submodel`` (names it lacks: the automatic guess on ``data``); None without one."""
    if init is None or submodel not in init.submodels:
        return None
    prev = init.submodels[submodel].parameters
    th = np.asarray(structure.theta0(data), float) if any(
        n not in prev for n in structure.names) else np.zeros(len(structure.names))
    for i, n in enumerate(structure.names):
        if n in prev:
            th[i] = prev[n]
    return th


def windowed(record, submodel: str, settings: FitSettings):
    """(record, data, prefilter report, window, notes, n) of ``submodel``: the analysis
    window of :func:`analysis_window` taken (a note says so), the prefilters applied
    (:func:`prepare`); ``n`` the whole record's samples. Shared by :func:`fit_base` and a
    given model's base (:func:`rigd.diagnose.given.given_base`)."""
    settings.check()
    n = record.n
    window = analysis_window(n, settings)
    notes = []
    if window != (0, n):
        notes.append(f"long record: analysed samples {window[0]}..{window[1]} of {n} "
                     f"(--range START:STOP chooses another window)")
        record = record.slice(*window)
    data, rep = prepare(record, submodel, settings.options, settings.runout)
    return record, data, rep, window, notes, n


def fit_base(record, submodel: str, settings: FitSettings) -> BaseFit:
    """Fit the base model of ``submodel`` on ``record`` (module docstring).

    ``record`` is the whole record; the window of :func:`analysis_window` is taken here.
    """
    from rigd.ident.greybox.submodels import structure_for
    from rigd.ident.hold import choose_hold
    from rigd.ident.pem import fit

    record, data, rep, window, notes, n = windowed(record, submodel, settings)
    es, vs = parts(data.n, settings)
    est_data = data.slice(es.start, es.stop)
    choice = choose_hold(submodel, est_data, record.meta, settings.hold, where=record.source)
    base = structure_for(submodel, data, hold=choice.hold)
    th0 = start_values(base, settings.init, submodel, est_data)
    res = fit(base, est_data, method=settings.method, theta0=th0)
    chosen = None
    if submodel == "generic":
        base, res, chosen = _generic_base(base, res, data, es, vs, choice.hold, settings)
    return BaseFit(submodel, data, es, vs, window, base, res, choice, rep, settings, chosen,
                   n, notes)


def _generic_base(mech, res, data, es: slice, vs: slice, hold: str, settings: FitSettings):
    """(structure, FitResult, order choice) of a generic record's base.

    The family, order and delays come from the data (:func:`rigd.ident.lti.order.
    choose_base`: general LTI, process or the mechanical n-DOF model ``mech``, fitted as
    ``res``). With ``settings.mechanical`` (an asked effect acts on a mechanical state: a
    stiffness, a restoring force) the base stays mechanical, with the parallel modes the
    data need (:func:`rigd.ident.greybox.order.choose_order`).
    """
    from rigd.ident.pem import evaluate, fit

    est_data = data.slice(es.start, es.stop)
    if settings.mechanical:
        from rigd.ident.greybox.order import choose_order

        modes = mechanical_modes(settings.order, mech.n)
        try:
            chosen = choose_order(mech, data, es, vs, modes,
                                  base_theta=res.theta if res.method == "oe" else None)
        except ValueError as exc:
            raise InputError(f"order {settings.order} refused: {exc}", "--order") from None
        if modes != "auto" and chosen.modes != modes:
            raise InputError(f"order {settings.order} refused: the mechanical base reached "
                             f"{chosen.modes} mode(s) of the {modes} asked ({chosen.reason})",
                             "--order")
        chosen.asked = settings.order
        chosen.delays = [0] * len(data.input_names)
        if chosen.structure is not mech:
            res = fit(chosen.structure, est_data, method=settings.method,
                      theta0=chosen.theta)
        return chosen.structure, res, chosen
    from rigd.ident.lti.candidates import settle
    from rigd.ident.lti.order import OrderRefused, choose_base

    try:
        chosen = choose_base(data, es, vs, settings.order, hold=hold, mechanical=mech,
                             mechanical_theta=res.theta)
    except OrderRefused as exc:
        raise InputError(str(exc), "--order") from None
    if chosen.structure is mech:   # fitted by the asked method already
        return mech, res, chosen
    skip = settle(chosen.structure.delays)
    if settings.method == "oe":
        # choose_base's parameters are output-error fits already, or a reference of more
        # states than it refines that its held-out check kept as it is: refitted to
        # convergence, such a model fits the estimation noise (DaISy evaporator: a
        # 60-state reference 60.94 % held out as kept, 33.98 % refitted)
        res = evaluate(chosen.structure, est_data, chosen.theta, skip=skip,
                       status="kept: the base choice's output-error parameters")
    else:
        res = fit(chosen.structure, est_data, method=settings.method, theta0=chosen.theta,
                  skip=skip)
    return chosen.structure, res, chosen


def mechanical_modes(order: str | int, dofs: int) -> str | int:
    """Modes of the mechanical base (one per output, ``dofs``, plus parallel modes) for
    ``--order`` (a number of states: 2 per mode); InputError when no mechanical model has
    that many states."""
    if order == "auto":
        return order
    n = int(order)
    if n % 2 or n < 2 * dofs:
        raise InputError(f"order {n} refused: the mechanical base (kept for an effect on a "
                         f"mechanical state) has 2 states per mode and one mode per output: "
                         f"an even number of states >= {2 * dofs} is needed", "--order")
    return n // 2


#: Most free parameters of the model that effects are added to which the refit moves with
#: the effects. Beyond it (a carried high-order reference: a 113-state model of a 3-input,
#: 6-output furnace has ≈ 1,200) the refit holds that model's parameters at their values and
#: fits the effects' and the output offsets only (:func:`held_base`): each finite-difference
#: Jacobian of a full refit costs one simulation per parameter and each trust-region step an
#: SVD of the (samples·outputs × parameters) Jacobian — one effect's refit took > 10 min.
MAX_REFIT_FREE = 300


def held_base(structure, method: str, fixed: Sequence[str] | None = None) -> list[str]:
    """Parameters of ``structure`` that a refit with effects holds: [] when it has at most
    :data:`MAX_REFIT_FREE` free parameters (``method``'s, ``fixed`` not counted); else
    every free one except its output offsets (the effects' gain in fit is then a lower
    bound: the base does not adapt to them)."""
    from rigd.ident.pem import free_mask

    names = list(structure.names)
    free = free_mask(structure, [n for n in (fixed or ()) if n in set(names)], method)
    if int(free.sum()) <= MAX_REFIT_FREE:
        return []
    off = set(structure.offset_index)
    return [n for i, n in enumerate(names) if free[i] and i not in off]


def refit_with(structure, theta: np.ndarray, effects: Sequence[Any], data_est, method: str,
               starts: Sequence[np.ndarray | None] = (None,), fixed=None,
               max_nfev: int | None = None):
    """``structure`` (fitted, parameters ``theta``) extended by ``effects`` and refitted.

    Parameters
    ----------
    structure, theta
        The fitted model the effects are added to (its parameters start at ``theta``).
    effects : sequence of Effect
        Applied in order (``effect.extend(structure)``).
    data_est : IdData
        Estimation part (the effects' bounds are made relative to it).
    method : {"pem", "oe"}
        As the base fit.
    starts : sequence
        Start values of the added parameters (None: the effects' own ``theta0``); each is
        fitted, the lowest estimation cost kept.
    fixed : list of str, optional
        Parameters kept at their start. On a ``structure`` of more than
        :data:`MAX_REFIT_FREE` free parameters its own are kept too (:func:`held_base`;
        the result's ``info["held_base"]`` counts them).

    Returns
    -------
    (extended structure, FitResult or None, th0 of the last start, names kept fixed)
        None when no start could be fitted; the names: ``fixed`` and the held base's.
    """
    from rigd.ident.pem import fit

    held = held_base(structure, method, fixed)   # names not in ``fixed`` already
    fixed = (list(fixed or []) + held) or None

    ext = structure
    for e in effects:
        ext = e.extend(ext)
    ext.bind_record(data_est)  # bounds relative to the record (rigd.effects.scales)
    lo, hi = ext.bounds()
    theta = np.asarray(theta, float)
    nb = theta.size
    if len(effects) == 1:  # the effect's own start: no base guess needed
        auto = np.asarray(effects[0].theta0_effect(structure, data_est), float)
    else:
        auto = np.asarray(ext.theta0(data_est), float)[nb:]
    best, th0 = None, None
    for ws in starts:
        te = auto if ws is None else np.asarray(ws, float)
        th0 = np.clip(np.concatenate([theta, te]), lo, hi)
        try:
            res = fit(ext, data_est, method=method, theta0=th0, max_nfev=max_nfev, fixed=fixed)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            continue
        if np.isfinite(res.cost) and (best is None or res.cost < best.cost):
            best = res
    if best is not None:
        best.info["held_base"] = len(held)
    return ext, best, th0, tuple(fixed or ())


def effects_for(effects: Sequence[Any], submodel: str) -> list[Any]:
    """Those of ``effects`` that concern ``submodel`` (``Effect.submodels``)."""
    return [eff for eff in effects if submodel in eff.submodels]
