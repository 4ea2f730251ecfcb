"""From a record to identified sub-models: prefilter, split, fit, validate (Sec. 4.4-4.5).

:func:`identify_record` is what ``rigd identify`` runs on one record:

1. prefilter (run-out F_r(φ), offsets, median 3 — :mod:`rigd.ident.prefilter`);
2. split: the first ``split`` (default 2/3) of the samples are the *estimation* part, the rest
   the *validation* part;
3. fit each asked sub-model by PEM (or OE) on the estimation part, from a previous model file's
   parameters if given, else from the automatic initial guess;
4. validate: the model is simulated over the whole record from its estimated initial state
   (inputs only, no measured outputs used) and the fit 100·(1 − NRMSE) is computed on the
   validation part (and on the estimation part).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from rigd.data.record import Record
from rigd.errors import InputError
from rigd.ident.iddata import IdData, channels_for
from rigd.ident.model import base_of
from rigd.ident.modelfile import ModelFile, Submodel, apply_effects
from rigd.ident.pem import fit_percent
from rigd.ident.pipeline import DEFAULT_SPLIT, prepare  # noqa: F401 - prepare: re-exported
from rigd.ident.prefilter import PrefilterOptions


def available_submodels(record: Record) -> list[str]:
    """Sub-models whose columns the record has (``generic`` for generic records)."""
    if record.is_generic:
        return ["generic"]
    out = []
    for sm in ("actuator", "bearing"):
        ins, outs = channels_for(record, sm)
        if record.has(*ins, *outs):
            out.append(sm)
    return out


def resolve_submodels(record: Record, asked: str = "auto") -> list[str]:
    """``auto`` | ``actuator`` | ``bearing`` | ``both`` | ``generic`` -> list of sub-models."""
    if asked == "auto":
        got = available_submodels(record)
        if not got:
            raise InputError("record has neither actuator (r_x, r_y, u_x, u_y) nor bearing "
                             "(u_x, u_y, e_x, e_y) columns, nor inputs/outputs metadata "
                             f"(columns: {', '.join(record.columns)})", record.source)
        return got
    if asked == "both":
        return ["actuator", "bearing"]
    if asked in ("actuator", "bearing", "generic"):
        return [asked]
    raise InputError(f"unknown model {asked!r} (use actuator, bearing, both, generic or auto)")


def estimate_x0(structure, theta: np.ndarray, data: IdData,
                rows: slice | None = None) -> np.ndarray:
    """theta with the initial-state entries (and constant output offsets, where the structure
    has them: the record's own zero) re-estimated on ``data`` by least squares.

    The free response is linear in x0 for the mechanical structures, so one simulation per
    state gives the regressors. ``rows``: the samples of ``data`` the least squares fit
    (default: all); the initial state is still the one at ``data``'s first sample, so
    ``rows`` = the estimation part and ``data`` = estimation + validation gives the
    validation part's state from the estimation part alone.
    """
    base = base_of(structure)  # the effects' parameters come after the base's
    idx = list(base.x0_index) + list(base.offset_index)
    if not idx:
        return np.asarray(theta, float)
    th = np.array(theta, float)
    th[idx] = 0.0
    y0 = np.asarray(structure.simulate(th, data))
    # perturb each initial state by a step at the data's scale (not 1.0: a cubic model on a
    # record in metres diverged from x0 = 1 m): output std for positions, its rate for
    # velocities; the free response is linear in x0 (nonlinear models: for small steps)
    ys = float(np.max(np.std(data.y, axis=0))) or 1.0
    vs = float(np.max(np.std(np.diff(data.y, axis=0), axis=0))) * float(data.fs) or ys
    # velocity states [p, ṗ] of a mechanical model (its parallel modes' initial values are
    # output amplitudes); other families: every state at y's scale
    vel = set(base.velocity_index)
    steps = np.array([vs if i in vel else ys for i in idx]) * 1e-2
    cols = []
    for i, d in zip(idx, steps):
        t1 = th.copy()
        t1[i] = d
        cols.append(((np.asarray(structure.simulate(t1, data)) - y0) / d).ravel())
    rows = slice(None) if rows is None else rows
    A = np.column_stack([c.reshape(data.y.shape)[rows].ravel() for c in cols])
    b = (data.y - y0)[rows].ravel()
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
        th[idx] = np.asarray(theta, float)[idx]  # keep the model's own initial state
        return th
    try:
        th[idx] = np.linalg.lstsq(A, b, rcond=None)[0]
    except np.linalg.LinAlgError:
        th[idx] = np.asarray(theta, float)[idx]
    return th


def samples_needed(structure) -> int:
    """Fewest samples a fitted model needs to be compared on a record: its initial states
    are estimated by least squares (one more sample than states), and at least 3."""
    base = base_of(structure)  # the effects' parameters come after the base's
    return max(3, len(list(base.x0_index)) + 1)


def residual_stats(y: np.ndarray, yhat: np.ndarray, names: list[str]) -> dict[str, Any]:
    """Per-output residual statistics: mean, std, rms, max |ε|, lag-1 autocorrelation."""
    out = {}
    for i, nm in enumerate(names):
        with np.errstate(over="ignore", invalid="ignore"):  # a diverged fit: inf/NaN, quietly
            e = y[:, i] - yhat[:, i]
            ec = e - e.mean()
            den = float(ec @ ec)
            r1 = float(ec[1:] @ ec[:-1] / den) if den > 0 else 0.0
            out[nm] = {"mean": float(e.mean()), "std": float(e.std()),
                       "rms": float(np.sqrt(np.mean(e ** 2))),
                       "max_abs": float(np.abs(e).max()), "autocorr_lag1": r1}
    return out


def identify_record(record: Record, submodels: list[str] | str = "auto", *,
                    runout: Record | None = None, options: PrefilterOptions | None = None,
                    method: str = "auto", init: ModelFile | None = None,
                    effects: Sequence[Any] = (), split: float = DEFAULT_SPLIT,
                    data_hash: str | None = None, hold: str | None = None,
                    order: str | int = "auto", est: slice | None = None,
                    val: slice | None = None, refit: Any = None) -> ModelFile:
    """Identify the asked sub-models of ``record``; returns a :class:`ModelFile`.

    Parameters
    ----------
    record : Record
    submodels : list of str or str
        Sub-models or one of ``auto``/``both``/``actuator``/``bearing``/``generic``.
    runout : Record, optional
        Run-out record at the same operating point (needs ``phi``).
    options : PrefilterOptions, optional
    method : {"auto", "pem", "oe"}
        ``auto``: prediction error for the rotor's sub-models, output error for a generic
        record (:data:`rigd.ident.pipeline.AUTO_METHOD`).
    init : ModelFile, optional
        Previous model: its parameters are the start values.
    effects : sequence of Effect, optional
        Effects to add to every sub-model they concern (objects with ``extend(structure)``
        and ``submodels``; from names: ``rigd.effects.resolve(names)``), applied in order.
    split : float
        Fraction of samples used for estimation (rest: validation).
    est, val : slice, optional
        Estimation and validation samples (both or neither; instead of ``split``, as
        ``rigd diagnose --est/--val``): the model is fitted on ``est``, simulated over the
        whole record and its fit reported on both.
    data_hash : str, optional
        ``sha256:...`` of the data file.
    hold : {"zoh", "foh", "auto"}, optional
        How the inputs behave between samples; default/``"auto"``: declared by the record,
        known for rigd recordings, else chosen from the data (:mod:`rigd.ident.hold`).
    order : "auto" or int
        Generic records: number of states, or ``auto`` to choose the family, order and
        delays from the data (:func:`rigd.ident.lti.order.choose_base`, as ``rigd
        diagnose``); with an effect on a mechanical state, modes of the mechanical base.
    refit : callable, optional
        ``refit(base_fit, effects, submodel, method, meta) -> (structure, FitResult)``: how
        the base is refitted with ``effects`` when no ``init`` is given (``rigd identify
        --add``: :func:`rigd.diagnose.added.refit_as_diagnosed`, as the diagnosis refits
        them); default: every effect parameter free, from the effects' own start values.
    """
    import dataclasses

    from rigd.ident.pipeline import FitSettings, effects_for, fit_base, method_for

    if isinstance(submodels, str):
        submodels = resolve_submodels(record, submodels)
    method_for(method, "generic")     # an unknown method: refused before any fit
    settings = FitSettings(method=method, split=None if est is not None else split, est=est,
                           val=val, hold=hold or "auto", order=order, init=init,
                           options=options, runout=runout)
    settings.check()
    effects = list(effects or [])
    # an asked effect that acts on a mechanical state (a stiffness, a restoring force)
    # needs the mechanical base (rigd.ident.pipeline.FitSettings.mechanical)
    settings.mechanical = any("mechanical" in e.requires
                              for e in effects_for(effects, "generic"))
    fitted = []
    for sm in submodels:
        used = method_for(method, sm)
        bf = fit_base(record, sm, dataclasses.replace(settings, method=used))
        applied = effects_for(effects, sm)
        if refit is not None and applied and init is None:
            _composable(bf.structure, applied, sm)
            try:
                structure, res = refit(bf, applied, sm, used, record.meta)
            except ValueError as exc:
                raise InputError(f"the {sm} model with {', '.join(e.name for e in applied)} "
                                 f"cannot be fitted on this record: {exc}", "--add") from None
        else:
            structure, res = _with_effects(bf, applied, sm, init, used)
        fitted.append((bf, structure, res))
    return model_file(record, fitted, data_hash, split if est is None else None)


def model_file(record: Record, fitted: Sequence[tuple[Any, Any, Any]],
               data_hash: str | None = None, split: float | None = None) -> ModelFile:
    """The :class:`ModelFile` of fitted sub-models of ``record``, as ``rigd identify -o``
    and ``rigd diagnose --save-model`` write it.

    Parameters
    ----------
    record : Record
        The whole record the sub-models were fitted on.
    fitted : sequence of (BaseFit, structure, FitResult)
        Per sub-model: how its base was fitted (:func:`rigd.ident.pipeline.fit_base`: the
        prefiltered data, window and split), the structure kept (the base or the base with
        effects) and its fit (``theta``, ``std``).
    data_hash : str, optional
        ``sha256:...`` of the data file.
    split : float, optional
        The estimation fraction, when the split was one.
    """
    subs: dict[str, Submodel] = {}
    prefilter_reports = {}
    split_info = {}
    for bf, structure, res in fitted:
        sm = bf.submodel
        prefilter_reports[sm] = bf.prefilter
        subs[sm] = _submodel(sm, bf, structure, res)
        a, es, vs = bf.window[0], bf.est, bf.val
        split_info = {"estimation": [a + es.start, a + es.stop],
                      "validation": [a + vs.start, a + vs.stop],
                      **({"fraction": split} if split is not None
                         and bf.window == (0, record.n) else {}),
                      "base": bf.to_json()}
    return ModelFile(record.fs, subs,
                     {"omega_rpm": record.omega_rpm, "p_inj_bar": record.p_inj_bar},
                     prefilter_reports, {"path": record.source, "sha256": data_hash,
                                         "n_samples": record.n}, split_info)


def _composable(structure, applied: list[Any], sm: str):
    """``structure`` with the effects ``applied``; InputError (``--add``) when the base
    cannot carry one, or two cannot be simulated together."""
    try:
        return apply_effects(structure, applied)
    except ValueError as exc:
        raise InputError(f"the {sm} model cannot take "
                         f"{', '.join(e.name for e in applied)}: {exc}", "--add") from None


def _with_effects(bf, applied: list[Any], sm: str, init: ModelFile | None, method: str):
    """(structure, fit result): the base of ``bf`` (rigd.ident.pipeline.BaseFit), refitted
    with the effects ``applied`` (start values from ``init`` where it has them)."""
    from rigd.ident.pipeline import refit_with, start_values

    structure, res = bf.structure, bf.result
    if not applied:
        return structure, res
    nb = len(structure.names)
    composed = _composable(structure, applied, sm)
    th_init = start_values(composed, init, sm, bf.est_data)
    starts = [None if th_init is None else th_init[nb:]]
    if th_init is None and len(applied) == 1:
        # an effect that starts from the fitted base (a mode effect: which mode, its scale)
        s0 = applied[0].start_on(structure, res.theta, bf.est_data)
        starts = starts if s0 is None else [s0]
    structure, res2, *_ = refit_with(structure, res.theta, applied, bf.est_data, method,
                                    starts=starts)
    if res2 is None:
        raise InputError(f"the {sm} model with {', '.join(e.name for e in applied)} "
                         "cannot be fitted on this record (every start failed)")
    return structure, res2


def _submodel(sm: str, bf, structure, res) -> Submodel:
    """The identified sub-model: fits on the estimation and validation parts, read-outs
    with the sanity warnings (flagged, never used silently), residual statistics."""
    from rigd.ident.sanity import model_warnings

    data, es, vs = bf.data, bf.est, bf.val
    theta, std = res.theta, res.std
    ysim = np.asarray(structure.simulate(theta, data))
    fe = fit_percent(data.y[es], ysim[es])
    fv = fit_percent(data.y[vs], ysim[vs])
    readouts = structure.readouts(theta)
    warn = model_warnings(structure, theta, res.info.get("at_bound"), std)
    if not np.all(np.isfinite(ysim)):
        warn.append("the model's simulated response is not finite on this record (the "
                    "fit diverged; its fit is not a number): do not use this model")
    warn += _refit_warnings(bf, structure, fv)
    warn += list(res.info.get("notes", ()))   # e.g. an effect fitted on a window (--add)
    if res.info.get("held_base"):
        from rigd.ident.pipeline import MAX_REFIT_FREE

        warn.append(f"the base model's {res.info['held_base']} free parameters (more than "
                    f"{MAX_REFIT_FREE}) were held in the refit with the effects: only the "
                    "effects' parameters and the output offsets moved")
    if warn:
        readouts = dict(readouts, warnings=warn)
    order_info = bf.order.to_json() if bf.order is not None else None
    sub = Submodel(sm, structure, theta, std, res.method,
                   {"estimation": fe.tolist(), "validation": fv.tolist(),
                    "validation_mean": float(np.mean(fv)), "outputs": data.output_names,
                    "input_hold": bf.hold.as_dict(),
                    **({"order": order_info} if order_info else {})},
                   readouts, residual_stats(data.y[vs], ysim[vs], data.output_names))
    sub.residual["iterations"] = {"nfev": res.nfev, "status": res.status}
    # the input level it was fitted at (a model used on another record: rigd.diagnose.given)
    u = data.u[es]
    sub.residual["input_rms"] = {n: float(np.sqrt(np.mean(u[:, i] ** 2)))
                                 for i, n in enumerate(data.input_names)}
    return sub


def _refit_warnings(bf, structure, fv: np.ndarray) -> list[str]:
    """``identify --add``: a warning when the model with the effects fits the validation part
    worse than the base model it extends (or below 0 %): the refit is flagged, not an
    improvement (:func:`rigd.ident.figures.refit_flag`); none for the base itself."""
    from rigd.ident.figures import REFIT_FLAGS, refit_flag

    if structure is bf.structure:
        return []
    vs = bf.val
    yb = np.asarray(bf.structure.simulate(bf.theta, bf.data))
    fb = float(np.mean(fit_percent(bf.data.y[vs], yb[vs])))
    fw = float(np.mean(fv))
    flag = refit_flag(fw, fb)
    if flag is None or flag == "diverged":  # a diverged model has its own warning
        return []
    return [f"with the effects added the validation fit is {fw:.2f} % against the base "
            f"model's {fb:.2f} %: the refit is {REFIT_FLAGS[flag]} (not an improvement)"]
