"""Prediction-error and output-error fitting of a grey-box structure (Sec. 4.5).

:func:`fit` minimises the sum of squared errors of either

* ``method="pem"``: the one-step-ahead predictor through the disturbance gain B_d (Eq. 5),
* ``method="oe"``: the simulation (output error, B_d unused),

with ``scipy.optimize.least_squares`` (trust-region reflective), each output weighted by
1/std(y). Iterations stop when the relative improvement of the cost falls below
``ftol = 1e-4`` (as the paper). Parameters are scaled internally by their typical size and
the Jacobian is a forward difference of the compiled predictor (one predictor run per
parameter) — for output error, columns of parameters the output is linear in are exact where
the structure offers them (:mod:`rigd.ident.jacobian`: the general LTI model's B, C, D, x0
and offsets), the optimiser's steps unchanged. Standard deviations come from the Jacobian
at the optimum: cov θ = σ² (JᵀJ)⁻¹ with σ² = SSE / (N − p).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from rigd.errors import InputError
from rigd.ident.figures import fit_percent
from rigd.ident.iddata import IdData
from rigd.ident.model import Model
from rigd.ident.trf import least_squares_trf

METHODS = ("pem", "oe")
_PENALTY = 1e3


@dataclass
class FitResult:
    """Result of :func:`fit`.

    Attributes
    ----------
    structure : Model
    theta, std : ndarray
        Estimates and their standard deviations (same order as ``structure.names``).
    method : str
        ``"pem"`` or ``"oe"``.
    fit_percent : ndarray (ny,)
        Simulation fit on the estimation data, %.
    cost : float
        Final weighted cost ½Σe².
    nfev, niter : int
    status : str
        Optimiser message.
    info : dict
        ``njev``, ``success``, ``n_samples``, ``skip`` and ``at_bound`` (bool per parameter:
        the bound was active when the optimiser stopped).
    """

    structure: Model
    theta: np.ndarray
    std: np.ndarray
    method: str
    fit_percent: np.ndarray
    cost: float
    nfev: int
    status: str
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def parameters(self) -> dict[str, dict[str, float]]:
        """name -> {"value", "std"}."""
        return {n: {"value": float(v), "std": float(s)}
                for n, v, s in zip(self.structure.names, self.theta, self.std)}

    def readouts(self) -> dict[str, Any]:
        return self.structure.readouts(self.theta)


def _scale(structure: Model, theta: np.ndarray) -> np.ndarray:
    """Typical parameter sizes; for a base with effects composed around it
    (rigd.effects.compose.Composed) the base's, then the effects' own."""
    if structure.base is None:
        s = np.asarray(structure.scale(theta), float)
        return s if s.shape == theta.shape else np.maximum(np.abs(theta), 1e-6)
    nb = len(structure.base.names)
    # an effect's parameters: their size, at least their typical size on this record
    # (rigd.effects: seconds relative to the rate, amplitudes to the signals), else 1
    typ = structure.typical()
    typ = 1.0 if typ is None or typ.shape != theta[nb:].shape else typ
    return np.concatenate([_scale(structure.base, theta[:nb]),
                           np.maximum(np.abs(theta[nb:]), typ)])


def has_predictor(structure: Model) -> bool:
    """True if ``structure`` is a base model (whose family may have a one-step predictor),
    not a base with effects composed around it (fitted by output error)."""
    return isinstance(structure, Model) and structure.base is None


def _bounds(structure: Model, npar: int):
    lo, hi = structure.bounds()
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if lo.shape == (npar,) and hi.shape == (npar,):
        return lo, hi
    return np.full(npar, -np.inf), np.full(npar, np.inf)


def _residual_fn(structure: Model, data: IdData, method: str, scale: np.ndarray,
                 free: np.ndarray, theta_full: np.ndarray, wy: np.ndarray, skip: int):
    y = data.y

    def res(z):
        th = theta_full.copy()
        th[free] = z * scale[free]
        if method == "pem":
            yh = structure.predict(th, data)
        else:
            yh = structure.simulate(th, data)
        if yh is None or not np.all(np.isfinite(yh)):
            return np.full(y[skip:].size, _PENALTY)
        return ((y[skip:] - yh[skip:]) * wy).ravel()

    return res


def free_mask(structure: Model, fixed: list[str] | None, method: str) -> np.ndarray:
    """Mask of the parameters the fit moves: not ``fixed``, and for output error neither
    the disturbance (``bd_*``) nor the noise parameters, which play no role in a simulation."""
    fixed_set = set(fixed or [])
    unknown = fixed_set - set(structure.names)
    if unknown:
        raise InputError(f"cannot fix unknown parameter(s) {sorted(unknown)}")
    fixed_set |= set(structure.fixed_names)
    free = np.array([n not in fixed_set for n in structure.names])
    if method == "oe":
        free &= np.array([not n.startswith("bd_") for n in structure.names])
        free[list(structure.noise_index)] = False
    return free


def _fit_scale(structure: Model, th0: np.ndarray, data: IdData) -> np.ndarray:
    """Scale of each parameter (:func:`_scale`), output offsets (generic structures) at the
    outputs' own scale, whatever their start value."""
    scale = _scale(structure, th0)
    off = list(structure.offset_index)
    if off:
        ys = np.maximum(data.y.std(axis=0), np.abs(data.y.mean(axis=0)))
        for k, i in enumerate(off):
            scale[i] = max(scale[i], float(ys[k]) or 1e-300)
    return scale


def _std(sol, free: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Standard deviation of each parameter from the Jacobian of the solution (weighted
    units -> parameter units); 0 for the fixed ones, NaN when the covariance cannot be had."""
    J = sol.jac
    nfree = int(free.sum())
    dof = max(int(sol.fun.size) - nfree, 1)
    s2 = 2.0 * sol.cost / dof
    std = np.zeros(len(free))
    try:
        cov = s2 * np.linalg.pinv(J.T @ J)
        std[free] = np.sqrt(np.clip(np.diag(cov), 0, None)) * scale[free]
    except np.linalg.LinAlgError:
        std[free] = np.nan
    return std


def _problem(structure: Model, data: IdData, method: str, theta: np.ndarray,
             fixed: list[str] | None, skip: int):
    """(free mask, scale, residual function of the scaled free parameters) of the weighted
    least-squares problem at ``theta``: what :func:`fit` solves and :func:`evaluate`
    evaluates (the structure already bound to ``data``)."""
    free = free_mask(structure, fixed, method)
    scale = _fit_scale(structure, theta, data)
    wy = 1.0 / np.maximum(data.y[skip:].std(axis=0), 1e-300)
    return free, scale, _residual_fn(structure, data, method, scale, free, theta, wy, skip)


def _fit_at(structure: Model, theta: np.ndarray, data: IdData, skip: int) -> np.ndarray:
    """Fit % per output of the simulation at ``theta`` (the first ``skip`` samples left out)."""
    ysim = structure.simulate(theta, data)
    return fit_percent(data.y[skip:], ysim[skip:])


def fit(structure: Model, data: IdData, *, method: str = "pem",
        theta0: np.ndarray | None = None, ftol: float = 1e-4, max_nfev: int | None = None,
        fixed: list[str] | None = None, skip: int = 0) -> FitResult:
    """Fit ``structure`` to ``data``.

    Parameters
    ----------
    structure : Model
    data : IdData
        Estimation data (prefiltered).
    method : {"pem", "oe"}
        Prediction error (one-step predictor) or output error (simulation).
    theta0 : ndarray, optional
        Start values; default ``structure.theta0(data)`` (automatic initial guess).
    ftol : float
        Stop when the relative improvement of the cost is below this (paper: 1e-4).
    max_nfev : int, optional
        Cap on residual evaluations (default 100 × number of free parameters).
    fixed : list of str, optional
        Parameter names kept at their start values.
    skip : int
        Samples at the start left out of the cost (transient).
    """
    if method not in METHODS:
        raise InputError(f"unknown fit method {method!r} (known: {', '.join(METHODS)})")
    # effects' bounds relative to this record (rate, length, spreads): rigd.effects.scales
    structure.bind_record(data)
    th0 = np.asarray(structure.theta0(data) if theta0 is None else theta0, float).copy()
    npar = len(structure.names)
    if method == "pem":
        try:
            if not has_predictor(structure):
                raise NotImplementedError
            structure.predict(th0, data.slice(0, 10))
        except NotImplementedError:
            method = "oe"
    if th0.shape != (npar,):
        raise InputError(f"start values have {th0.size} entries, the structure needs {npar}")
    free, scale, fun = _problem(structure, data, method, th0, fixed, skip)
    lo, hi = _bounds(structure, npar)
    z0 = th0[free] / scale[free]
    zlo, zhi = lo[free] / scale[free], hi[free] / scale[free]
    if np.any(np.isfinite(zlo) | np.isfinite(zhi)):
        z0 = np.clip(z0, np.where(np.isfinite(zlo), zlo + 1e-9, zlo),
                     np.where(np.isfinite(zhi), zhi - 1e-9, zhi))
    nfree = int(free.sum())
    bounded = bool(np.any(np.isfinite(zlo) | np.isfinite(zhi)))
    # MINPACK Levenberg-Marquardt when unbounded; trust-region reflective (on the Jacobian's
    # QR factor: rigd.ident.trf) when an effect or the base brings bounds.
    zb = (zlo, zhi) if bounded else (-np.inf, np.inf)
    jac = "2-point"
    if method == "oe":  # exact columns where the output is linear in the parameter
        from rigd.ident.jacobian import linear_jacobian

        wy = 1.0 / np.maximum(data.y[skip:].std(axis=0), 1e-300)
        pair = linear_jacobian(structure, data, fun, free, scale, th0, wy, skip, zb, 1e-6)
        if pair is not None:
            fun, jac = pair
    # a trial step of a candidate that diverges overflows inside scipy's cost and Jacobian
    # products: the fit judges that step by its (inf) cost and steps back; numpy's overflow
    # warnings would only reach the operator's terminal as library noise (the fit's own
    # figures say when a model diverges)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        opts = dict(ftol=ftol, xtol=1e-10, gtol=1e-10, x_scale="jac", diff_step=1e-6,
                    max_nfev=max_nfev or 100 * nfree)
        if bounded:
            sol = least_squares_trf(fun, z0, jac=jac, bounds=zb, **opts)
        else:
            sol = least_squares(fun, z0, jac=jac, method="lm", **opts)
        theta = th0.copy()
        theta[free] = sol.x * scale[free]
        std = _std(sol, free, scale)
    fp = _fit_at(structure, theta, data, skip)
    at_bound = np.zeros(npar, bool)  # trust-region reflective: the active bounds at the end
    at_bound[free] = np.asarray(getattr(sol, "active_mask", np.zeros(nfree)), float) != 0
    return FitResult(structure, theta, std, method, fp, float(sol.cost), int(sol.nfev),
                     str(sol.message), {"njev": int(sol.njev or 0), "success": bool(sol.success),
                                        "n_samples": data.n, "skip": skip,
                                        "at_bound": at_bound})


def evaluate(structure: Model, data: IdData, theta: np.ndarray, *, skip: int = 0,
             status: str = "kept") -> FitResult:
    """The output-error :class:`FitResult` of ``structure`` at ``theta``, without iterating.

    For parameters already chosen by an output-error fit and a held-out check
    (:func:`rigd.ident.lti.order.choose_base`: refined candidates, and references of more
    states than it refines, kept as they are): a second fit would move them only where the
    held-out check did not look (a large model refitted to convergence fits the estimation
    noise). Cost, fit and the parameters' standard deviations come from one forward-difference
    Jacobian at ``theta`` (``nfev`` counts its evaluations), as :func:`fit` reports them.

    Parameters
    ----------
    structure, data
        As :func:`fit` (``data``: the estimation part).
    theta : ndarray
        The parameters, kept.
    skip : int
        Samples at the start left out of the cost.
    status : str
        The ``status`` reported.
    """
    from types import SimpleNamespace

    structure.bind_record(data)
    th = np.asarray(theta, float).copy()
    free, scale, fun = _problem(structure, data, "oe", th, None, skip)
    z = th[free] / scale[free]
    from rigd.ident.jacobian import linear_jacobian

    wy = 1.0 / np.maximum(data.y[skip:].std(axis=0), 1e-300)
    pair = linear_jacobian(structure, data, fun, free, scale, th, wy, skip,
                           (-np.inf, np.inf), 1e-6)
    if pair is not None:  # exact columns where the output is linear in the parameter
        r0 = pair[0](z)
        jac = pair[1](z)
    else:
        r0 = fun(z)
        jac = np.empty((r0.size, z.size))
        for k in range(z.size):
            h = 1e-6 * max(1.0, abs(z[k]))
            zk = z.copy()
            zk[k] += h
            jac[:, k] = (fun(zk) - r0) / h
    cost = 0.5 * float(r0 @ r0)
    std = _std(SimpleNamespace(jac=jac, cost=cost, fun=r0), free, scale)
    fp = _fit_at(structure, th, data, skip)
    return FitResult(structure, th, std, "oe", fp, cost, int(z.size + 1), status,
                     {"njev": 1, "success": True, "n_samples": data.n, "skip": skip,
                      "at_bound": np.zeros(len(th), bool)})
