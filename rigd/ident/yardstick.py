"""The yardstick: what plain black-box linear models reach on the same split.

Every fit rigd prints (``identify``, ``compare --part validation``, ``diagnose``) is put
beside two references fitted on the *same* estimation part and scored on the *same*
validation part, by the same :func:`rigd.ident.figures.fit_percent`, with the validation
part's state from the estimation part (free run, nothing fitted on the held-out samples):

* a least-squares ARX model (:func:`rigd.ident.lti.arx.select_arx`: orders 1..10, the
  order and the per-input delays chosen on the estimation part alone);
* a subspace model (:func:`rigd.ident.lti.subspace.n4sid`, order from the singular values).

When rigd's model is worse than the better of the two by at least
:data:`rigd.ident.thresholds.MIN_FIT_GAIN` points, the output carries a warning: the error
left is *reachable* by a linear model, so it is not noise (:mod:`rigd.diagnose.unexplained`
uses the same references as its measure of what is reachable).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigd.ident.figures import fit_percent
from rigd.ident.thresholds import MIN_FIT_GAIN

#: ARX orders (na = nb) tried by the yardstick (an equation-error model of a lightly damped
#: structure needs a high order to come near its output-error fit: up to 30, as the
#: MATLAB-style comparisons users make)
ARX_ORDERS = tuple(range(1, 11)) + (15, 20, 30)


@dataclass
class Reference:
    """One black-box reference on the split: its validation fit (mean over outputs, %),
    per output, how it was chosen, and its validation residual (in the data's units)."""

    name: str
    fit_percent: float
    per_output: list[float]
    detail: dict[str, Any]
    residual: np.ndarray = field(repr=False)

    def to_json(self) -> dict[str, Any]:
        return {"fit_percent": round(self.fit_percent, 3),
                "fit_per_output": [round(v, 3) for v in self.per_output], **self.detail}


@dataclass
class Yardstick:
    """The references on one split and the model they are compared with.

    ``model_fit``: rigd's validation fit (mean over outputs, %); ``references``: those that
    could be fitted (a failure is listed in ``skipped`` with its reason).
    """

    model_fit: float
    references: list[Reference]
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def best(self) -> Reference | None:
        ok = [r for r in self.references if np.isfinite(r.fit_percent) and r.fit_percent >= 0]
        return max(ok, key=lambda r: r.fit_percent) if ok else None

    @property
    def gap(self) -> float:
        """Fit points the best reference reaches beyond the model (≤ 0: none)."""
        b = self.best
        return float(b.fit_percent - self.model_fit) if b is not None else 0.0

    @property
    def worse(self) -> bool:
        """The model is worse than a plain linear reference by ≥ MIN_FIT_GAIN points."""
        return self.gap >= MIN_FIT_GAIN

    def reachable(self, model_fit: float) -> dict[str, Any] | None:
        """What is reachable for a model fitting ``model_fit`` % on the same split: the
        best reference's validation residual, fit and label
        (:func:`rigd.diagnose.unexplained.report`'s ``reference``), None without one."""
        b = self.best
        if b is None:
            return None
        return {"residual": b.residual, "fit": b.fit_percent, "model_fit": float(model_fit),
                "label": f"a plain {_LABEL[b.name]} ({_detail(b)})"}

    def to_json(self) -> dict[str, Any]:
        return {"text": self.describe(), "model_fit_percent": round(self.model_fit, 3),
                **{r.name: r.to_json() for r in self.references},
                **({"skipped": dict(self.skipped)} if self.skipped else {}),
                "gap_points": round(self.gap, 3), "model_worse": bool(self.worse)}

    def describe(self) -> str:
        """One line: what each reference reaches on the same split."""
        parts = [f"{_LABEL[r.name]} ({_detail(r)}) {r.fit_percent:.2f} %"
                 + (NO_HOLD if r.fit_percent < 0 else "") for r in self.references]
        parts += [f"{_LABEL.get(k, k)}: not fitted ({v})" for k, v in self.skipped.items()]
        return ("on the same split (validation from the estimation part's state): "
                + "; ".join(parts) + f"; this model {self.model_fit:.2f} %")

    def warning(self) -> str | None:
        """The warning when the model is worse than a plain linear reference, else None."""
        b = self.best
        if b is None or not self.worse:
            return None
        return (f"this model fits {self.model_fit:.2f} % on validation, {self.gap:.2f} points "
                f"below a plain {_LABEL[b.name]} ({_detail(b)}: {b.fit_percent:.2f} %) on the "
                "same split: a linear model reaches more than this one")


_LABEL = {"arx": "ARX", "subspace": "subspace model"}
#: said of a reference below 0 % (its held-out error larger than the output's spread): it
#: is no measure of what a linear model reaches here, and nothing is compared with it
NO_HOLD = (" (below 0 %: it does not hold on the held-out part, e.g. unstable there; no "
           "measure of what a linear model reaches)")


def _detail(r: Reference) -> str:
    if r.name == "arx":
        d = ", ".join(str(k) for k in r.detail["delays_samples"])
        return f"order {r.detail['order']}, input delay(s) {d} samples"
    return f"order {r.detail['order']}"


def _free_run(model, u: np.ndarray, y: np.ndarray, n_est: int) -> np.ndarray:
    """Validation simulation of a LinearModel from the estimation part's end state."""
    from rigd.ident.lti.linear import heldout

    return heldout(model, u, y, n_est)[1]


def measure(u: np.ndarray, y: np.ndarray, est: slice, val: slice, model_fit: float,
            fs: float | None = None) -> Yardstick | None:
    """The yardstick of a model fitting ``model_fit`` % on ``val`` after being fitted on
    ``est`` of the (prefiltered) data ``u`` (n, nu), ``y`` (n, ny).

    The references see the samples from ``est``'s start to ``val``'s end (a gap between
    the parts only carries the predictor's state); None when the validation part does not
    follow the estimation part (no free run from its state).
    """
    u = np.atleast_2d(np.asarray(u, float).T).T
    y = np.atleast_2d(np.asarray(y, float).T).T
    e0, e1 = est.indices(len(u))[:2]
    v0, v1 = val.indices(len(u))[:2]
    if v0 < e1:
        return None
    uu, yy = u[e0:v1], y[e0:v1]
    n_est, k0 = e1 - e0, v0 - e0
    refs, skipped = [], {}
    from rigd.ident.lti.arx import select_arx
    from rigd.ident.lti.subspace import n4sid

    def add(name, model, detail):
        with np.errstate(all="ignore"):
            yh = _free_run(model, uu, yy, k0)
            fp = fit_percent(yy[k0:], yh)
        fp = np.where(np.isfinite(fp), fp, -np.inf)
        refs.append(Reference(name, float(np.mean(fp)), [float(v) for v in fp], detail,
                              yy[k0:] - yh))

    try:
        sel = select_arx(uu[:n_est], yy[:n_est], ARX_ORDERS, fs=fs)
        add("arx", sel.model.to_linear(), {"order": sel.order,
                                           "delays_samples": list(sel.nk)})
    except (ValueError, np.linalg.LinAlgError) as exc:
        skipped["arx"] = str(exc)
    try:
        ss = n4sid(uu[:n_est], yy[:n_est], "auto", fs=fs)
        add("subspace", ss.model, {"order": int(ss.order)})
    except (ValueError, np.linalg.LinAlgError) as exc:
        skipped["subspace"] = str(exc)
    return Yardstick(float(model_fit), refs, skipped)
