"""Diagnose a given model on another record (``rigd diagnose --model M.yaml DATA``).

A model fitted on one record (one force level, one operating point) is taken as the base of
the diagnosis of another: its physical parameters are kept as saved; only its initial state
and constant output offsets, which belong to a record and not to the system, are estimated
on this record's estimation part (as ``rigd compare`` does). The forward selection then asks
which catalogue effect explains what the model misses here.

Beside it, the same structure is refitted on this record from the model's parameters, and
what moved is said in words: the fit the refit gains on the held-out part, and each mode's
frequency and damping as saved and as refitted here ("7.32 Hz, ζ 0.005 in the model ->
7.22 Hz, ζ 0.015 on this record"). A mode that softens and damps more on a record of larger
input is the signature of amplitude-dependent stiffness and damping (a joint, friction, a
clearance); on a record of the same level, of another operating point.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.errors import InputError

#: a mode's frequency or damping ratio "moved" when it changed by more than this share
MODE_SHIFT = 0.01


def given_base(record, submodel: str, settings, model, model_path: str = "--model"):
    """(BaseFit, report) of ``submodel`` of ``record`` with the base taken from ``model``
    (:class:`rigd.ident.modelfile.ModelFile`), not fitted.

    The record's window, prefilters and split are this record's (as
    :func:`rigd.ident.pipeline.fit_base` makes them); the structure and parameters are the
    model's, with the initial state and output offsets estimated on the estimation part.
    ``report``: the JSON of the comparison with the same structure refitted here, with its
    ``text``.
    """
    from rigd.ident.model import base_of
    from rigd.ident.pem import evaluate, fit
    from rigd.ident.pipeline import BaseFit, parts, windowed
    from rigd.ident.workflow import estimate_x0

    if submodel not in model.submodels:
        raise InputError(f"the model has no {submodel!r} sub-model (it has: "
                         f"{', '.join(model.submodels)})", model_path)
    sm = model.submodels[submodel]
    record, data, rep, window, notes, n = windowed(record, submodel, settings)
    spec = base_of(sm.structure).spec()
    for what, have in (("inputs", data.input_names), ("outputs", data.output_names)):
        want = spec.get(what)
        if want is not None and list(want) != list(have):
            raise InputError(f"the model's {what} are {', '.join(want)}; the record's are "
                             f"{', '.join(have)}", model_path)
    if abs(model.fs - data.fs) > 1e-9 * model.fs:
        raise InputError(f"the model is sampled at {model.fs:g} Hz, the record at "
                         f"{data.fs:g} Hz", model_path)
    es, vs = parts(data.n, settings)
    est_data = data.slice(es.start, es.stop)
    structure = sm.structure
    theta = estimate_x0(structure, np.asarray(sm.theta, float), data, rows=es)
    res = evaluate(structure, est_data, theta, status="the given model, not refitted")
    from rigd.ident.hold import HoldChoice

    choice = HoldChoice(base_of(structure).hold, "the model's")
    bf = BaseFit(submodel, data, es, vs, window, structure, res, choice, rep, settings, None,
                 n, notes)
    refit = fit(structure, est_data, method=settings.method, theta0=theta)
    return bf, drift_report(bf, sm, theta, np.asarray(refit.theta, float), model_path)


def _val_fit(structure, theta, bf) -> float:
    from rigd.ident.pem import fit_percent
    from rigd.ident.workflow import estimate_x0

    th = estimate_x0(structure, theta, bf.data, rows=bf.est)
    y = np.asarray(structure.simulate(th, bf.data))
    return float(np.mean(fit_percent(bf.data.y[bf.val], y[bf.val])))


def _modes(structure, theta) -> list[dict[str, float]]:
    return [m for m in structure.readouts(theta).get("modes", []) if "f_n_hz" in m]


def _matched(given: list[dict[str, float]], here: list[dict[str, float]]):
    """Pairs (given mode, refitted mode), one to one, nearest in frequency first (a refit
    may reorder the modes); a mode with no refitted one within a factor 1.5 is left out.
    In the given modes' order."""
    d = sorted((abs(np.log(b["f_n_hz"] / a["f_n_hz"])), i, j)
               for i, a in enumerate(given) for j, b in enumerate(here))
    used_i, used_j, out = set(), set(), []
    for dist, i, j in d:
        if dist <= np.log(1.5) and i not in used_i and j not in used_j:
            used_i.add(i)
            used_j.add(j)
            out.append((i, given[i], here[j]))
    return [(a, b) for _, a, b in sorted(out, key=lambda t: t[0])]


def _in_band(modes: list[dict[str, float]], bf) -> list[dict[str, float]]:
    """The modes this record's input excites, by the mode site's rule
    (:func:`rigd.effects.mode_site.excited_by`). Modes outside the band are fitted from no
    input power: nothing is said of them."""
    from rigd.effects.mode_site import excited_by

    excited = excited_by(bf.data, bf.est)
    return [m for m in modes if excited(m["f_n_hz"], m["zeta"])]


def drift_report(bf, sm, theta, refit_theta, model_path: str) -> dict[str, Any]:
    """The given model against its structure refitted on this record: held-out fits, the
    modes that moved, the input level of both records where the model file has it, and
    one sentence (``text``)."""
    from rigd.ident.thresholds import MIN_FIT_GAIN

    s = bf.structure
    given, here = _val_fit(s, theta, bf), _val_fit(s, refit_theta, bf)
    pairs = []
    for m0, m1 in _matched(_in_band(_modes(s, theta), bf), _modes(s, refit_theta)):
        df = m1["f_n_hz"] / m0["f_n_hz"] - 1.0
        dz = m1["zeta"] / max(m0["zeta"], 1e-12)
        pairs.append({"model_hz": m0["f_n_hz"], "model_zeta": m0["zeta"],
                      "here_hz": m1["f_n_hz"], "here_zeta": m1["zeta"],
                      "moved": bool(abs(df) > MODE_SHIFT or abs(dz - 1) > 10 * MODE_SHIFT)})
    level = _level_ratio(bf, sm)
    moved = [p for p in pairs if p["moved"]]
    words = [f"the model from {model_path} fits this record's held-out part {given:.2f} %; "
             f"its structure refitted here fits {here:.2f} %"]
    if here - given < MIN_FIT_GAIN:
        words.append("its parameters carry to this record (what it misses is below)")
    else:
        words.append(f"{here - given:.1f} points better: its parameters do not carry to "
                     "this record")
    for p in moved:
        words.append(f"mode {p['model_hz']:.3g} Hz, ζ {p['model_zeta']:.3g} in the model -> "
                     f"{p['here_hz']:.3g} Hz, ζ {p['here_zeta']:.3g} here")
    if moved and here - given >= MIN_FIT_GAIN:
        soft = any(p["here_hz"] < p["model_hz"] and p["here_zeta"] > p["model_zeta"]
                   for p in moved)
        if level is not None and abs(np.log(level)) > np.log(1.2):
            words.append(f"this record's input is {level:.2g}× the model's: "
                         + ("a mode that softens and damps more with amplitude is "
                            "amplitude-dependent stiffness and damping (a joint: friction, "
                            "a clearance), not a linear model's"
                            if soft == (level > 1) else
                            "the modes move with the input level: the system is not linear "
                            "in its amplitude"))
        else:
            words.append("at the same input level: another operating point or a change "
                         "of the system between the records")
    return {"model": model_path, "fit_percent_given": round(given, 3),
            "fit_percent_refitted": round(here, 3), "modes": pairs,
            "input_level_ratio": None if level is None else float(level),
            "text": "; ".join(words)}


def _level_ratio(bf, sm) -> float | None:
    """This record's input RMS over the model's record's (the model file's
    ``input_rms``), the largest ratio over the inputs; None where the file has none."""
    saved = (sm.residual or {}).get("input_rms") or {}
    if not saved:
        return None
    u = bf.data.u[bf.est]
    ratios = [float(np.sqrt(np.mean(u[:, i] ** 2))) / saved[n]
              for i, n in enumerate(bf.data.input_names) if saved.get(n)]
    return max(ratios, key=lambda r: abs(np.log(r))) if ratios else None
