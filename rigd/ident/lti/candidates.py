"""A candidate base model and its scores (BIC on the estimation part, held-out fit), shared
by the order selection (:mod:`rigd.ident.lti.order`) and the families that compete in it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rigd.ident.thresholds import MIN_FIT_GAIN

#: validation fit (points) within which a candidate counts as good as the best: the
#: practical significance of every fit gain (its one home: rigd.ident.thresholds)
MIN_GAIN = MIN_FIT_GAIN


@dataclass(eq=False)
class Candidate:
    """One model tried: family, states, the fitted model and its scores."""

    family: str
    states: int
    structure: Any
    theta: np.ndarray
    bic: float
    fit_est: float
    fit_val: float
    npar: int
    skip: int = 0

    def to_json(self) -> dict[str, Any]:
        return {"family": self.family, "states": self.states, "bic": round(self.bic, 2),
                "fit_estimation": round(self.fit_est, 3),
                "fit_validation": round(self.fit_val, 3), "parameters": self.npar}


def _pct(y, yh) -> np.ndarray:
    from rigd.ident.pem import fit_percent

    return fit_percent(y, yh)


def score(structure, theta, data, est: slice, val: slice, skip: int = 0
          ) -> tuple[float, float, float]:
    """(BIC on est, mean fit on est, mean fit on val) of ``structure`` at ``theta`` simulated
    over the whole record; +inf / −inf when the simulation is not finite. ``skip``: samples
    at the start of the estimation part left out (their outputs depend on inputs before the
    record, through the delays: :func:`settle`)."""
    yh = np.asarray(structure.simulate(theta, data))
    if not np.all(np.isfinite(yh)):
        return np.inf, -np.inf, -np.inf
    y = np.asarray(data.y)
    ye, yhe = y[est][skip:], yh[est][skip:]
    e = ye - yhe
    n, ny = e.shape
    p = len(structure.names) - len(structure.noise_index)
    s2 = np.maximum(np.mean(e ** 2, axis=0), 1e-300 * np.maximum(np.var(ye, 0), 1e-300))
    bic = float(n * np.sum(np.log(s2)) + p * np.log(n * ny))
    return (bic, float(np.mean(_pct(ye, yhe))),
            float(np.mean(_pct(y[val], yh[val]))) if val.stop > val.start else -np.inf)




def settle(delays) -> int:
    """Samples at the start whose outputs depend, through the input delays, on inputs before
    the record (unknown: the simulator holds the first input): left out of every fit and
    criterion of the base-model choice."""
    return int(max(list(delays) or [0]))
