"""What the input delays a base model carries are worth on held-out data.

The general LTI and process families take a per-input delay in whole samples, chosen before
their order (:mod:`rigd.ident.lti.order`). A lag of the dynamics — two tanks in cascade, a
response of high relative degree — also shows its first significant response late, and the
criterion of the base choice can then prefer a model that stands in for the lag with a delay.
A delay is a transport delay only when the data pay for it: :func:`delay_worth` refits the
same family and order with no delay and reports the held-out fit points that costs
(compared by the diagnosis with :data:`rigd.ident.thresholds.MIN_FIT_GAIN`: the practical
significance of every fit gain).
"""

from __future__ import annotations

import numpy as np

from rigd.ident.lti.candidates import Candidate, score, settle


def _without_delays(structure):
    """The same family and order with every input delay 0 (its record length kept)."""
    spec = dict(structure.spec())
    spec["delays"] = [0] * len(spec["inputs"])
    m = type(structure).from_spec(spec)
    if structure._n_est is not None:
        m.set_record(structure._n_est)
    return m


def delay_worth(structure, theta, data, est: slice, val: slice,
                max_nfev: int | None = None) -> float | None:
    """Held-out fit points (:func:`rigd.ident.lti.candidates.score`) that ``structure`` at
    ``theta`` (fitted on ``est`` of ``data``) loses when refitted without its input delays,
    or None when it carries none (or its family takes no delay).

    The delay-free model starts from ``theta`` and from its family's own start on the
    estimation part (the subspace poles of a general LTI model of as many states, the time
    constant grid of a process model), each refined by output error
    (:func:`rigd.ident.lti.order._refine`); the better held-out fit counts. Both models are
    scored on the same samples (those of the delayed model: :func:`settle`).
    """
    from rigd.ident.lti.order import _clip, _refine, lti_candidates
    from rigd.ident.lti.process import ProcessModel
    from rigd.ident.lti.statespace import StateSpaceModel

    delays = [int(d) for d in structure.delays]
    if not delays or max(delays) <= 0 or not isinstance(structure,
                                                        (StateSpaceModel, ProcessModel)):
        return None
    skip = settle(delays)
    d_est = data.slice(est.start, est.stop)
    _, _, fit_with = score(structure, theta, data, est, val, skip)
    plain = _without_delays(structure)
    starts = [(plain, np.asarray(theta, float))]
    if isinstance(plain, ProcessModel):
        starts.append((plain, plain.theta0(d_est)))
    else:   # any split of as many states into pairs, real poles and integrators
        starts += [(c.structure, c.theta) for c in lti_candidates(
            data, d_est, est, val, plain.nx, plain.delays, plain.hold, skip=skip)]
    best = -np.inf
    for m, th in starts:
        th = _clip(m, th)
        b, fe, fv = score(m, th, data, est, val, skip)
        if not np.isfinite(b):
            continue
        c = _refine(Candidate("", m.nx, m, th, b, fe, fv, len(m.names), skip),
                    data, d_est, est, val, max_nfev)
        best = max(best, c.fit_val)
    if not np.isfinite(fit_with):
        return None
    return float(fit_with - best) if np.isfinite(best) else float("inf")
