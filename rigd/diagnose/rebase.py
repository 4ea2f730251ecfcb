"""The base's order and delays chosen again once a static curve is in the model.

A linear order search on a record with a static nonlinearity (Hammerstein, Wiener) fits the
curve's distortion with whatever linear dynamics fit it best: a plant of two lags behind an
exponential valve curve came out as one lag and a 4-sample delay (held-out 30 %), and the
diagnosis then named the delay beside the curve. A block-oriented model's linear part is
chosen *with* its curves, as MATLAB's ``nlhw`` estimates them together; here, when the forward
selection added an effect of an input or output site, the diagnosis is run again from
general LTI bases of one and two more states (their delays checked at that order,
:func:`alternatives`) over the effects the first diagnosis added, and the one whose final
model fits the held-out part best is kept if it beats the first by at least ``MIN_FIT_GAIN``
points (:func:`best_final`; rigd.diagnose.diagnosis then diagnoses it over the whole
catalogue, which must still beat the first) — the rule that
already decides between the general LTI and the mechanical base
(rigd.diagnose.diagnosis.better_on_mechanical).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: linear bases of 1 … ALTERNATIVES more states the diagnosis is run from again
ALTERNATIVES = 2
#: effects whose addition makes the base's order and delays questionable (a static curve)
CURVES = ("static_nonlinearity",)


def alternatives(bf, sd) -> list[Any]:
    """Linear bases of more states than the base of ``bf`` (rigd.ident.pipeline.BaseFit):
    the general LTI model of exactly ``states + k`` states, k = 1 … :data:`ALTERNATIVES`,
    its delays checked at that order (:func:`rigd.ident.lti.order.choose_base`) — when the
    diagnosis ``sd`` added a static curve and the order was chosen from the data; else [].

    More states, not other candidates of the linear search: what the curve's distortion
    took from the linear part is a lag or a delay standing in for a missing state (the
    exponential valve curve before two lags: one lag + 4 samples of delay), and a
    block-oriented model's linear part is of the plant's own order. Where the exact-order
    model has input delays, the same order without them is tried too (the delays were
    checked on the linear model, without the curve).
    """
    from rigd.ident.lti.order import MAX_STATES, OrderRefused, choose_base

    if not any(s.added in CURVES for s in sd.steps[1:]):
        return []
    ch = bf.order
    if ch is None or getattr(ch, "asked", "auto") != "auto" or ch.family == "mechanical":
        return []
    out = []
    for k in range(1, ALTERNATIVES + 1):
        n = int(ch.states) + k
        if n > MAX_STATES:
            break
        try:
            c = choose_base(bf.data, bf.est, bf.val, order=n, hold=bf.hold.hold)
        except (OrderRefused, ValueError, np.linalg.LinAlgError):
            continue
        out.append(c)
        if any(c.delays):
            z = _without_delays(bf, n)
            if z is not None:
                out.append(z)
    return out


def _without_delays(bf, n: int):
    """The general LTI model of ``n`` states and no input delay on ``bf``'s split (the same
    start and refinement as an order asked, :mod:`rigd.ident.lti.order`), or None."""
    from rigd.ident.lti.candidates import settle
    from rigd.ident.lti.order import BaseChoice, _refine, lti_candidates

    d_est = bf.data.slice(bf.est.start, bf.est.stop)
    zero = [0] * len(d_est.input_names)
    cands = [c for c in lti_candidates(bf.data, d_est, bf.est, bf.val, n, zero, bf.hold.hold,
                                       skip=settle(zero)) if np.isfinite(c.bic)]
    if not cands:
        return None
    best = _refine(min(cands, key=lambda c: c.bic), bf.data, d_est, bf.est, bf.val, None)
    return BaseChoice(best.structure, best.theta, "lti", n, zero, cands,
                      f"order {n}, no input delay", n)


def _curves(sd) -> list[str]:
    return [s.added for s in sd.steps[1:] if s.added]


def best_final(sd, alts: list[tuple[Any, Any]]):
    """(diagnosis kept, why): among ``alts`` ([(candidate, its diagnosis)]) the one whose
    final model fits the held-out part best replaces ``sd`` when it is at least
    ``MIN_FIT_GAIN`` points above ``sd``'s final fit."""
    from rigd.ident.thresholds import MIN_FIT_GAIN

    if not alts:
        return sd, None
    # within MIN_FIT_GAIN of the best final fit, the fewest delay samples, then states: what
    # the held-out part does not pay for is not kept
    top = max(d.final.fit_percent for _, d in alts)
    cand, alt = min((ca for ca in alts if ca[1].final.fit_percent >= top - MIN_FIT_GAIN),
                    key=lambda ca: (sum(ca[0].delays), ca[0].states))
    a, b = sd.final.fit_percent, alt.final.fit_percent
    path = " -> ".join(f"{s.added or 'base'} {s.fit_percent:.2f} %" for s in alt.steps)
    what = (f"{cand.family}, {cand.states} state(s), input delays "
            f"{list(cand.structure.delays)}")
    if b >= a + MIN_FIT_GAIN:
        return alt, (f"with the static curve in, the linear part chosen again: from {what} "
                     f"{path}, against {a:.2f} % from the first base — kept (rigd identify "
                     f"--order {cand.states} --add {','.join(_curves(alt))} fits that order; "
                     f"its delays are checked there without the curve)")
    return sd, (f"with the static curve in, the linear part tried again from {what}: "
                f"{path}; the first base's {a:.2f} % kept")
