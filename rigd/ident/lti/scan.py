"""The cheap part of the base-model choice: delays and order scanned on subspace models.

:func:`rigd.ident.lti.order.choose_base` needs, for several per-input delays and every order
up to the most the record supports, a criterion and a held-out figure. Fitting the modal
family (:mod:`rigd.ident.lti.statespace`) for each of them is what made the choice slow; a
subspace model (:mod:`rigd.ident.lti.subspace`, PO-MOESP with the output-error step for B, D
and x0) of the same delays and order is the same linear class and costs one decomposition
per delay vector (every order follows from it by shift invariance). So:

* :func:`scan_orders` — for one delay vector, the subspace models of 1 … ``limit`` states
  on the estimation part (inputs shifted by the delays), each scored by the Bayesian
  information criterion of its free-run error on the estimation part and its free-run fit
  on the held-out part (simulated on from the estimation part's initial state);
* :func:`scan_delays` — the delay vectors tried: none, the estimate
  (:func:`rigd.ident.lti.delay.estimate_delays`) and fractions of it (the first significant
  lag of a response of high relative degree — a chain of masses, a cascade of lags — comes
  late, so the estimate can be far too long), then per input one sample either way from
  the best while the criterion improves at the best order.

Only the few best (delay, order) points are turned into the modal family and refined by
output error (:func:`rigd.ident.lti.order.choose_base`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigd.ident.figures import fit_percent
from rigd.ident.simulate import shift_inputs

#: orders scanned past the last improvement of the criterion
PATIENCE = 4
#: the subspace models of the scan get the output-error step for B, D and x0
REFINE_BD = True
#: most a scanned model's slowest pole may grow over the record (poles outside the unit
#: circle are brought onto it, :func:`rigd.ident.lti.subspace.clamp_poles`; a model that
#: still diverges is not ranked)
MAX_GROWTH = 10.0
#: largest order served by the first (short-horizon) decomposition of a scan
FIRST_STAGE = 12
#: fractions of the estimated delay tried before the sample-by-sample search
FRACTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)


@dataclass(eq=False)
class ScanPoint:
    """One subspace model of the scan: its delays, states, criterion and held-out fit."""

    delays: tuple[int, ...]
    states: int
    bic: float
    fit_est: float
    fit_val: float
    A: np.ndarray


def _bic(e: np.ndarray, y: np.ndarray, p: int) -> float:
    n, ny = e.shape
    s2 = np.maximum(np.mean(e ** 2, axis=0), 1e-300 * np.maximum(np.var(y, 0), 1e-300))
    return float(n * np.sum(np.log(s2)) + p * np.log(n * ny))


def parameters(states: int, nu: int, ny: int) -> int:
    """Free parameters of a modal model of ``states`` states (poles, B, C less the fixed
    entries, x0, offsets): what the criterion charges."""
    return states * (1 + nu + ny) + ny


def scan_orders(data, est: slice, val: slice, delays, limit: int,
                patience: int = PATIENCE, orders=None, feedthrough: bool = True,
                skip: int = 0) -> list[ScanPoint]:
    """Subspace models of 1 … ``limit`` states (or ``orders``) for one delay vector, scored
    (module docstring); the scan stops ``patience`` orders after the last improvement.

    The decomposition's horizon grows with the largest order it serves (and its cost with
    the square of the horizon): orders up to :data:`FIRST_STAGE` come from a short one, a
    longer one is made only when the scan gets past them. ``feedthrough``: the subspace
    models have a D (a model of inputs held by a first-order hold does: the input moves
    within the sample; behind a zero-order hold a plant is strictly proper). ``skip``: samples
    at the start of the estimation part left out of the criterion (the same for every delay
    vector compared)."""
    u = shift_inputs(np.ascontiguousarray(data.u, float), list(delays))
    y = np.asarray(data.y, float)
    if orders is not None:
        return _score_orders(data, u, y, est, val, tuple(delays), list(orders), None,
                             feedthrough=feedthrough, skip=skip)[0]
    first = list(range(1, min(limit, FIRST_STAGE) + 1))
    out, stopped = _score_orders(data, u, y, est, val, tuple(delays), first, patience,
                                 feedthrough=feedthrough, skip=skip)
    if not stopped and limit > FIRST_STAGE:
        best = min((p.bic for p in out), default=np.inf)
        since = len(out) - 1 - int(np.argmin([p.bic for p in out])) if out else 0
        more, _ = _score_orders(data, u, y, est, val, tuple(delays),
                                list(range(FIRST_STAGE + 1, limit + 1)), patience,
                                best, since, feedthrough, skip)
        out += more
    return out


def _score_orders(data, u, y, est, val, delays, todo, patience, best=np.inf, since=0,
                  feedthrough=True, skip=0):
    """(points, stopped early) for the orders ``todo`` from one decomposition."""
    from rigd.ident.lti.subspace import _Decomposition

    nu, ny = u.shape[1], y.shape[1]
    ue, ye = u[est], y[est]
    try:
        dec = _Decomposition(ue, ye, max(todo), None, data.fs, feedthrough)
    except (ValueError, np.linalg.LinAlgError):
        return [], True
    stop = max(est.stop, val.stop) if val.start >= est.start else est.stop
    k = est.stop - est.start
    out: list[ScanPoint] = []
    for nx in todo:
        try:
            m = dec.model(nx, refine=REFINE_BD, stabilise=True)
        except (ValueError, np.linalg.LinAlgError):
            continue
        with np.errstate(all="ignore"):
            yh = m.simulate(u[est.start:stop])
        rho = float(np.max(np.abs(np.linalg.eigvals(m.A))))
        if not np.all(np.isfinite(yh)) or len(yh) * np.log(max(rho, 1e-300)) > np.log(
                MAX_GROWTH):
            point = ScanPoint(delays, nx, np.inf, -np.inf, -np.inf, m.A)
        else:
            b = _bic(ye[skip:] - yh[skip:k], ye[skip:], parameters(nx, nu, ny))
            fe = float(np.mean(fit_percent(ye[skip:], yh[skip:k])))
            if val.stop <= val.start:
                fv = -np.inf
            elif val.start >= est.start:
                fv = float(np.mean(fit_percent(y[val], yh[val.start - est.start:
                                                          val.stop - est.start])))
            else:   # validation before the estimation part: a free run from rest
                with np.errstate(all="ignore"):
                    yv = m.simulate(u[val], np.zeros(nx))
                fv = float(np.mean(fit_percent(y[val], yv)))
                fv = fv if np.isfinite(fv) else -np.inf
            point = ScanPoint(delays, nx, b, fe, fv, m.A)
        out.append(point)
        if point.bic < best:
            best, since = point.bic, 0
        else:
            since += 1
            if patience is not None and since >= patience:
                return out, True
    return out, False


def _best(points: list[ScanPoint], margin: float) -> ScanPoint | None:
    """Lowest criterion among the points whose held-out fit is within ``margin`` of the
    best held-out fit."""
    ok = [p for p in points if np.isfinite(p.bic) and np.isfinite(p.fit_val)]
    if not ok:
        return None
    top = max(p.fit_val for p in ok)
    return min((p for p in ok if p.fit_val >= top - margin), key=lambda p: p.bic)


def scan_delays(data, est: slice, val: slice, estimate, limit: int, margin: float,
                hold: str = "foh", orders=None) -> list[ScanPoint]:
    """Every scan point tried (module docstring): delay vectors ``FRACTIONS`` × ``estimate``
    over all orders (or only ``orders``), then per input ±1 sample at the best order while
    the criterion improves."""
    est_d = [int(d) for d in estimate]
    ft = hold == "foh"
    skip = max(est_d + [0]) + 2
    tried: dict[tuple[int, ...], list[ScanPoint]] = {}
    for f in FRACTIONS:
        dl = tuple(int(round(f * d)) for d in est_d)
        if dl not in tried:
            tried[dl] = scan_orders(data, est, val, dl, limit, feedthrough=ft, skip=skip,
                                    orders=orders)
    points = [p for ps in tried.values() for p in ps]
    best = _best(points, margin)
    if best is None:
        return points
    for j in range(len(est_d)):
        for step in (-1, 1):
            while True:
                dl = list(best.delays)
                dl[j] += step
                if dl[j] < 0 or tuple(dl) in tried:
                    break
                got = scan_orders(data, est, val, dl, limit, orders=[best.states],
                                  feedthrough=ft, skip=skip)
                tried[tuple(dl)] = got
                points += got
                if not got or not got[0].bic < best.bic:
                    break
                best = got[0]
    return points


def ranked(points: list[ScanPoint], margin: float, keep: int) -> list[ScanPoint]:
    """The ``keep`` best distinct (delays, states) points — admissible ones (held-out fit
    within ``margin`` of the best) by criterion — and the admissible one with the fewest
    states (the subspace poles are not the output-error optimum: a few extra states can
    make up for that in the scan and not after the refit, where fewer parameters win)."""
    ok = [p for p in points if np.isfinite(p.bic) and np.isfinite(p.fit_val)]
    if not ok:
        return []
    top = max(p.fit_val for p in ok)
    adm = sorted((p for p in ok if p.fit_val >= top - margin), key=lambda p: p.bic)
    out, seen = [], set()
    for p in adm:
        if (p.delays, p.states) not in seen:
            seen.add((p.delays, p.states))
            out.append(p)
        if len(out) >= keep:
            break
    few = min(adm, key=lambda p: (p.states, p.bic))
    if keep > 1 and (few.delays, few.states) not in seen:
        out.append(few)
    return out
