"""Delay first, then order: the generic base model (family, order, delays) from the data.

:func:`choose_base` is what ``rigd identify`` and ``rigd diagnose`` run on a record that is
not a rotor's (``generic``):

1. **delays** — per input, before any order is chosen: :func:`rigd.ident.lti.delay.
   estimate_delays` (ARX impulse response and prewhitened cross-correlation) on the
   estimation part; the lag of the first response becomes a delay in samples for the hold
   used (ZOH: nk − 1, FOH: nk);
2. **delays and order, cheaply** (:mod:`rigd.ident.lti.scan`): subspace models (one
   decomposition per delay vector) of 1, 2, … states for the delays 0, ¼, ½, ¾ and all of
   the estimate (the first significant lag of a response of high relative degree comes
   late), then per input one sample either way at the best order; each is scored by the
   Bayesian information criterion of its free run on the estimation part,
   BIC = Σ_outputs N·ln(σ²_i) + p·ln(N·ny), and its held-out fit; the scan stops a few
   orders after the last improvement;
3. **the best few** (:data:`REFINED`, lowest BIC among those whose held-out fit is within
   :data:`MIN_GAIN` points of the best, and the one with the fewest states) become the
   modal family: subspace poles, gains, initial state and offsets by least squares
   (:mod:`rigd.ident.lti.modal`; a slow real pole also as an explicit integrator), refined
   by output error (:func:`rigd.ident.pem.fit`); a refined one with an integrator competes
   beside the same model without it (:func:`_without_integrator`);
   The yardstick's references join them (:mod:`rigd.ident.lti.references`): the ARX and
   subspace models selected on the estimation part alone are carried whole (poles, B, C, D;
   x0 and offsets by least squares) into modal models of their order (up to
   :data:`~rigd.ident.lti.references.REF_MAX_STATES` states), refined likewise — the refit
   kept only when it lowers the criterion — when their held-out fit before the refit is
   within :data:`REF_MARGIN` of the scan's best and they have at most :data:`MAX_STATES`
   states;
4. **family** — they compete with the grey-box mechanical n-DOF model (one DOF per output,
   when given) and the low-order process models (:mod:`rigd.ident.lti.process`) by the same
   criterion: among the *admissible* candidates (held-out fit within :data:`MIN_GAIN` of
   the best) the lowest BIC wins — unless a model with fewer parameters fits the held-out
   part at least as well — and an admissible grey-box mechanical model whose every DOF is
   a mode (a complex pole pair) is kept (its parameters are physical and the state-level
   effects need it; an overdamped one is a lag, not a structure).

The first samples whose outputs depend, through the delays, on inputs before the record are
left out of every criterion and fit (:func:`~rigd.ident.lti.candidates.settle`).

``order=N`` fits the LTI family with exactly N states, or refuses with the reason
(:class:`OrderRefused`): never silently another order.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.ident.lti.candidates import MIN_GAIN, Candidate, score, settle
from rigd.ident.lti.modal import gains_by_least_squares, subspace_poles_by_order
from rigd.ident.lti.statespace import StateSpaceModel

#: most states tried by ``order="auto"`` (and accepted by ``order=N``)
MAX_STATES = 30
#: LTI candidates (the subspace scan's best) turned into the modal family and refined
REFINED = 3
#: a reference's model (:mod:`rigd.ident.lti.references`) is refined by output error when its
#: held-out fit before the refit is within this many points of the scan's best candidate's
REF_MARGIN = 2.0


class OrderRefused(ValueError):
    """``order=N`` cannot be fitted; the message says why."""


@dataclass
class BaseChoice:
    """The chosen base model and how it was chosen (printed, and ``order`` in ``--json``)."""

    structure: Any
    theta: np.ndarray
    family: str
    states: int
    delays: list[int]
    candidates: list[Candidate] = field(default_factory=list)
    reason: str = ""
    asked: str | int = "auto"
    scan: list = field(default_factory=list)

    @property
    def modes(self) -> int:
        """Complex pairs (oscillatory modes) of the chosen model."""
        from rigd.ident.readouts import modes

        lp = self.structure.linear_part(self.theta)
        return sum(1 for m in modes(lp) if "f_n_hz" in m)

    def fit_by_modes(self) -> dict[str, float]:
        """Best held-out fit of the candidates by their number of oscillatory modes
        (complex pairs; the mechanical n-DOF model: one per output)."""
        out: dict[str, float] = {}
        for c in self.candidates:
            m = (c.structure.ny if c.family == "mechanical"
                 else c.structure.nc if c.family == "lti" else None)
            if m is None or not np.isfinite(c.fit_val):
                continue
            out[str(m)] = max(out.get(str(m), -np.inf), round(float(c.fit_val), 3))
        return dict(sorted(out.items(), key=lambda kv: int(kv[0])))

    def describe(self) -> str:
        fam = {"lti": "general LTI", "mechanical": "mechanical n-DOF",
               "process": "process"}.get(self.family, self.family)
        what = self.structure.describe() or f"{self.states} states"
        return (f"{fam} model, {what}, input delays {self.delays} samples "
                f"({'order asked: ' + str(self.asked) if self.asked != 'auto' else self.reason})")

    def to_json(self) -> dict[str, Any]:
        by_states: dict[str, float] = {}
        for c in self.candidates:
            if c.family == "lti":
                k = str(c.states)
                by_states[k] = max(by_states.get(k, -np.inf), round(c.fit_val, 3))
        return {"modes": self.modes, "family": self.family, "states": self.states,
                "delays_samples": list(self.delays), "asked": self.asked,
                "validation_fit_by_modes": self.fit_by_modes(),
                "validation_fit_by_states": by_states,
                "criterion": "BIC on the estimation part; held-out fit within "
                             f"{MIN_GAIN} points of the best",
                "candidates": [c.to_json() for c in self.candidates], "reason": self.reason}


def input_delays(d_est, hold: str) -> list[int]:
    """Per-input delay (samples) of the estimation data for a model with input ``hold``."""
    from rigd.ident.lti.delay import estimate_delays

    est = estimate_delays(np.asarray(d_est.u, float), np.asarray(d_est.y, float))
    return [int(e.delay_zoh if hold == "zoh" else e.nk) for e in est]


def lti_candidates(data, d_est, est, val, states: int, delays, hold,
                   poles: dict | None = None, skip: int | None = None) -> list[Candidate]:
    """LTI models of ``states`` states from the subspace poles (``poles``: by order, from
    :func:`~rigd.ident.lti.modal.subspace_poles_by_order`; computed when not given) and, for
    a slow real pole, the same with an explicit integrator; gains by least squares (the
    first ``skip`` samples left out: default :func:`~rigd.ident.lti.candidates.settle`)."""
    skip = settle(delays) if skip is None else skip
    if poles is None:
        poles = subspace_poles_by_order(d_est, [states], delays)
    lam = poles.get(states, [])
    if len(lam) == 0:
        return []
    slow = 2 * np.pi * float(data.fs) / max(d_est.n, 1)
    variants = [(lam, 0)]
    reals = [v for v in lam if v.imag == 0]
    if reals and abs(reals[0].real) < slow:
        variants.append(([v for v in lam if v is not reals[0]], 1))
    out = []
    for poles, ni in variants:
        pairs = [v for v in poles if v.imag > 0]
        real = [v for v in poles if v.imag == 0]
        m = StateSpaceModel(d_est.input_names, d_est.output_names, data.fs, len(pairs),
                            len(real), ni, delays, hold)
        if m.nx != states:
            continue
        m.set_record(d_est.n)
        try:
            th = gains_by_least_squares(m, pairs + real + [0j] * ni, d_est, skip)
        except (np.linalg.LinAlgError, ValueError):
            continue
        th = _clip(m, th)
        b, fe, fv = score(m, th, data, est, val, skip)
        out.append(Candidate("lti", states, m, th, b, fe, fv, len(m.names), skip))
    return out


def reference_candidates(data, d_est, est: slice, val: slice, models, hold: str, skip: int,
                         limit: int) -> list[Candidate]:
    """General LTI candidates carrying the reference ``models``
    (:func:`rigd.ident.lti.references.reference_models`) of at most ``limit`` states whole:
    :func:`rigd.ident.lti.references.carried_candidates`; ``skip``: samples left out of every
    criterion (the same for all candidates)."""
    from rigd.ident.lti.references import carried_candidates

    return carried_candidates(data, d_est, est, val, models, hold, skip, limit)


def _clip(model, theta):
    lo, hi = model.bounds()
    return np.clip(theta, np.where(np.isfinite(lo), lo + 1e-9, lo),
                   np.where(np.isfinite(hi), hi - 1e-9, hi))


def _refine(cand: Candidate, data, d_est, est, val, max_nfev) -> Candidate:
    from rigd.ident.pem import fit

    try:
        res = fit(cand.structure, d_est, method="oe", theta0=cand.theta, max_nfev=max_nfev,
                  skip=cand.skip)
    except (np.linalg.LinAlgError, ValueError):
        return cand
    b, fe, fv = score(cand.structure, res.theta, data, est, val, cand.skip)
    if not np.isfinite(b) or b > cand.bic:
        return cand
    return Candidate(cand.family, cand.states, cand.structure, res.theta, b, fe, fv, cand.npar,
                     cand.skip)


def admissible(cands: list[Candidate]) -> list[Candidate]:
    """Candidates whose held-out fit is within :data:`MIN_GAIN` of the best one's."""
    ok = [c for c in cands if np.isfinite(c.bic) and np.isfinite(c.fit_val)]
    if not ok:
        return []
    top = max(c.fit_val for c in ok)
    return [c for c in ok if c.fit_val >= top - MIN_GAIN]


def choose_base(data, est: slice, val: slice, order: str | int = "auto", hold: str = "foh",
                mechanical=None, mechanical_theta=None, process: bool = True,
                max_states: int = MAX_STATES, max_nfev: int | None = None,
                references: bool = True) -> BaseChoice:
    """Family, order and delays of the base model of a generic record (module docstring).

    Parameters
    ----------
    data : IdData
        The whole (prefiltered) record; ``est``/``val`` its estimation/validation parts.
    order : "auto" or int
        ``auto``, or the number of states of the LTI model to fit exactly.
    hold : {"zoh", "foh"}
        Input between samples.
    mechanical : Model, optional
        The grey-box mechanical n-DOF structure to compete (``mechanical_theta``: already
        fitted on the estimation part).
    process : bool
        Let the process family compete (SISO pairs, :mod:`rigd.ident.lti.process`).
    references : bool
        Let general LTI models from the poles of the ARX and subspace references compete
        (:mod:`rigd.ident.lti.references`).
    """
    from rigd.ident.lti.modal import poles_from_discrete
    from rigd.ident.lti.references import REF_MAX_STATES, reference_models
    from rigd.ident.lti.scan import ranked, scan_delays

    d_est = data.slice(est.start, est.stop)
    delays = input_delays(d_est, hold)
    want = None if order == "auto" else order
    if want is not None:
        return _exact(data, d_est, est, val, want, delays, hold, max_states, max_nfev)
    limit = min(max_states, _most_states(d_est))
    points = scan_delays(data, est, val, delays, limit, MIN_GAIN, hold)
    best = ranked(points, MIN_GAIN, REFINED)
    refs = reference_models(d_est) if references else []
    # one criterion for every candidate: the same samples left out (the longest delay; a
    # carried reference is also tried one sample later with a first-order hold)
    skip = max([settle(p.delays) for p in best] + [settle(delays)]
               + [settle(r[2]) + (hold == "foh") for r in refs])
    from_refs = reference_candidates(data, d_est, est, val, refs, hold, skip, REF_MAX_STATES)
    cands: list[Candidate] = list(from_refs)
    for p in best:
        poles = {p.states: poles_from_discrete(p.A, float(data.fs))}
        cands += lti_candidates(data, d_est, est, val, p.states, list(p.delays), hold, poles,
                                skip)
    if best:
        delays = list(best[0].delays)
    if process:
        from rigd.ident.lti.process import process_candidates

        cands += process_candidates(data, d_est, est, val, delays, hold, skip)
    if mechanical is not None:
        from rigd.ident.pem import fit

        th = (mechanical_theta if mechanical_theta is not None else
              fit(mechanical, d_est, method="oe", max_nfev=max_nfev).theta)
        b, fe, fv = score(mechanical, th, data, est, val, skip)
        cands.append(Candidate("mechanical", 2 * mechanical.ny, mechanical, np.asarray(th),
                               b, fe, fv, len(mechanical.names), skip))
    choice = _pick(cands, data, d_est, est, val, max_nfev, from_refs)
    choice.scan = points
    return choice


def _pick(cands, data, d_est, est, val, max_nfev, always=()) -> BaseChoice:
    ok = admissible(cands)
    if not ok:
        raise OrderRefused("no candidate model could be simulated on this record")
    # refine (output error) the LTI candidates (those of the scan's best points) and the
    # best of every other family; then decide on the refined scores
    best_by_family: dict[str, Candidate] = {}
    for c in sorted(cands, key=lambda c: c.bic):
        if np.isfinite(c.bic):
            best_by_family.setdefault(c.family, c)
    # per model tried by the scan (delays, states) its best variant (with or without an
    # integrator), admissible or not: the scores before the refit are not the final ones
    # (a carried reference of more than MAX_STATES states is never one of them, whatever its
    # BIC: it competes as it is, below)
    per_point = _best_per_point([c for c in cands if c.family == "lti" and np.isfinite(c.bic)
                                 and c.states <= MAX_STATES])
    lti_ok = per_point[:REFINED + 1]
    # the references' carried models are refined too when their held-out fit before the
    # refit is near the scan's best, no scan candidate of as many states or fewer fits as
    # well and they have at most MAX_STATES states (an output-error refit of up to 30 states
    # is the costly step); the others compete as they are
    top = max((c.fit_val for c in lti_ok), default=-np.inf)
    as_is = []
    for ref in _best_per_point([c for c in always if np.isfinite(c.bic)]):
        if any(ref is c for c in lti_ok):
            continue
        covered = any(c.states <= ref.states and c.fit_val >= ref.fit_val - MIN_GAIN
                      for c in lti_ok)
        small = ref.states <= MAX_STATES
        (lti_ok if ref.fit_val >= top - REF_MARGIN and not covered and small
         else as_is).append(ref)
    refined = [_refine(c, data, d_est, est, val, max_nfev) for c in lti_ok]
    refined += [_refine(p, data, d_est, est, val, max_nfev)
                for p in (_without_integrator(c, data, d_est, est, val) for c in refined)
                if p is not None] + as_is
    best_by_family.pop("lti", None)
    if "process" in best_by_family:
        best_by_family["process"] = _refine(best_by_family["process"], data, d_est, est, val,
                                            max_nfev)
    final = refined + list(best_by_family.values())
    ok = admissible(final)
    mech = [c for c in ok if c.family == "mechanical" and _oscillates(c)]
    if mech:
        pick, why = mech[0], (f"the mechanical n-DOF model's held-out fit is within {MIN_GAIN} "
                              "points of the best")
    else:
        pick = min(ok, key=lambda c: c.bic)
        why = (f"lowest BIC among the models whose held-out fit is within {MIN_GAIN} points of "
               "the best")
        # validation check: parameters the held-out part does not pay for are not kept
        simpler = [c for c in ok if c.npar < pick.npar and c.fit_val >= pick.fit_val]
        if simpler:
            pick = min(simpler, key=lambda c: c.bic)
            why = ("a model with fewer parameters fits the held-out part as well as the "
                   "lowest-BIC one")
    delays = list(pick.structure.delays) or [0] * len(d_est.input_names)
    return BaseChoice(pick.structure, pick.theta, pick.family, pick.states, delays,
                      cands + [c for c in final if all(c is not x for x in cands)], why)


def _without_integrator(cand: Candidate, data, d_est, est: slice, val: slice
                        ) -> Candidate | None:
    """The refined LTI candidate ``cand`` without its last explicit integrator (None when
    it has none), its other parameters kept: it competes beside ``cand``. The integrators
    are the last states (``StateSpaceModel.block_states``), so every parameter of the model
    without one is a parameter of ``cand``.

    An integrator variant is built from a slow real pole before any refit
    (:func:`lti_candidates`); after the output-error refit its gain can be nothing (a
    first-order heater fitted with a spare state: gain 2e-5 ± 2e-5), and the model would
    carry a pole at zero, an infinite static gain and an "integrator" reading the data do
    not pay for. The same model without that state then fits as well with fewer parameters
    and wins by the criterion (or by the validation check) in :func:`_pick`."""
    m = cand.structure
    if cand.family != "lti" or m.ni < 1 or m.nx < 2:
        return None
    p = StateSpaceModel(m.input_names, m.output_names, m.fs, m.nc, m.nr, m.ni - 1,
                        list(m.delays), m.hold, m.feedthrough, m.output_offsets,
                        m.norm_rows[:-1])
    p.set_record(d_est.n)
    index = {n: i for i, n in enumerate(m.names)}
    th = _clip(p, np.asarray([cand.theta[index[n]] for n in p.names], float))
    b, fe, fv = score(p, th, data, est, val, cand.skip)
    return Candidate("lti", p.nx, p, th, b, fe, fv, len(p.names), cand.skip)


def _oscillates(cand: Candidate) -> bool:
    """Every DOF of a mechanical candidate is a mode (a complex pole pair): an overdamped
    DOF is two real poles — a heater's lag fitted as a mass on a spring — which the LTI and
    process families carry with fewer parameters and without a mechanical reading."""
    from rigd.ident.readouts import modes

    lp = cand.structure.linear_part(cand.theta)
    return sum(1 for m in modes(lp) if "f_n_hz" in m) >= cand.structure.ny


def _best_per_point(cands: list[Candidate]) -> list[Candidate]:
    """Per (delays, states) the candidate of lowest BIC (with or without an integrator),
    lowest BIC first."""
    per_point: dict[tuple, Candidate] = {}
    for c in sorted(cands, key=lambda c: c.bic):
        per_point.setdefault((tuple(c.structure.delays), c.states), c)
    return list(per_point.values())


def _most_states(d_est) -> int:
    """Most states a record supports: ≥ 10 samples per parameter of the LTI model."""
    nu, ny = len(d_est.input_names), len(d_est.output_names)
    per_state = 1 + nu + ny  # pole, B row, C column, x0
    return max(1, int((d_est.n / 10 - ny) // per_state))


def _exact(data, d_est, est, val, want, delays, hold, max_states, max_nfev) -> BaseChoice:
    try:
        n = int(want)
    except (TypeError, ValueError):
        raise OrderRefused(f"order must be 'auto' or a number of states, got {want!r}") from None
    if n < 1:
        raise OrderRefused(f"order {n}: a model needs at least 1 state")
    top = min(max_states, _most_states(d_est))
    if n > top:
        why = (f"at most {max_states} states are fitted" if n > max_states else
               f"the estimation part ({d_est.n} samples) supports at most {top} states "
               "(10 samples per parameter)")
        raise OrderRefused(f"order {n} refused: {why}")
    from rigd.ident.lti.scan import ranked, scan_delays

    # the delays checked at the asked order (the estimate alone can be far too long), and
    # the estimate kept as a candidate (the subspace scan's criterion at a low order can
    # drift to ever longer delays: a record started far from rest), scored on the same
    # samples
    got = ranked(scan_delays(data, est, val, delays, n, MIN_GAIN, hold, orders=[n]),
                 MIN_GAIN, 1)
    options = [list(delays)] + [list(g.delays) for g in got
                                if list(g.delays) != list(delays)]
    skip = max(settle(dl) for dl in options)
    cands = [c for dl in options
             for c in lti_candidates(data, d_est, est, val, n, dl, hold, skip=skip)
             if np.isfinite(c.bic)]
    if not cands:
        raise OrderRefused(f"order {n} refused: no {n}-state model could be estimated and "
                           "simulated on this record")
    best = min(cands, key=lambda c: c.bic)
    best = _refine(best, data, d_est, est, val, max_nfev)
    return BaseChoice(best.structure, best.theta, "lti", n, list(best.structure.delays),
                      cands, f"order {n} asked", n)
