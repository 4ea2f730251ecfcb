"""Trust-region reflective least squares on the QR factor of a tall Jacobian.

:func:`rigd.ident.pem.fit` minimises ½‖f(z)‖² over a few dozen parameters z and a residual f
of n·ny samples (hundreds of thousands on a long multi-output record). The trust-region
reflective method of ``scipy.optimize.least_squares`` (``method="trf"``, Branch, Coleman and
Li 1999) takes an SVD of the whole (m + p) × p augmented Jacobian at every iteration: on a
210,000 × 40 Jacobian that SVD costs about a second and was half of an identification.

Every use the method makes of the Jacobian J is through ‖J s‖, Jᵀf and that SVD, so it can
run on the p × p triangular factor R of J = Q R and on Qᵀf instead (one Householder QR of
[J | f] per Jacobian, no Q formed):

* the gradient Jᵀf = Rᵀ(Qᵀf), the column norms of J are those of R (``x_scale="jac"``);
* the augmented matrix [J·d; D] = [Q 0; 0 I]·[R·d; D], so its singular values and right
  vectors are those of the 2p × p matrix [R·d; D], and Uᵀ[f; 0] = U₂ᵀ[Qᵀf; 0];
* the model of the cost along a step, ‖J s‖², is ‖R s‖².

The steps, radii and stopping tests are scipy's own (its ``_lsq`` helpers, pinned with scipy
in constraints.txt), so the iterates are those of ``least_squares(method="trf",
tr_solver="exact")`` up to rounding; only the cost of a step changes (O(m p²) for the QR,
the rest O(p³)). The cost itself is always taken from the full residual.
"""

from __future__ import annotations

import numpy as np
from numpy.linalg import norm
from scipy.linalg import svd
from scipy.optimize import OptimizeResult
from scipy.optimize._lsq.common import (
    CL_scaling_vector,
    check_termination,
    compute_jac_scale,
    find_active_constraints,
    make_strictly_feasible,
    solve_lsq_trust_region,
    update_tr_radius,
)
from scipy.optimize._lsq.least_squares import TERMINATION_MESSAGES
from scipy.optimize._lsq.trf import select_step
from scipy.optimize._numdiff import approx_derivative

__all__ = ["least_squares_trf"]

#: rows of one block of the tall-skinny QR (:func:`_factor`)
ROWS = 1024


def _factor(J: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, Qᵀf) of J = Q R (p × p upper triangular, p-vector), from one QR of [J | f].

    The QR is taken by blocks of :data:`ROWS` rows (a tall-skinny QR: each block's R, then
    the R of their stack), which stays in the cache where one Householder sweep over the
    whole tall matrix is limited by memory: about 4× faster on 210,000 × 40, the same
    factor up to the signs of its rows."""
    m, p = J.shape
    if m < p:  # fewer residuals than parameters: J and f padded with zero rows (Q = I)
        return np.vstack((J, np.zeros((p - m, p)))), np.concatenate((f, np.zeros(p - m)))
    Rs = [np.linalg.qr(np.column_stack((J[i:i + ROWS], f[i:i + ROWS])), mode="r")
          for i in range(0, m, ROWS)]
    Rf = Rs[0] if len(Rs) == 1 else np.linalg.qr(np.vstack(Rs), mode="r")
    return Rf[:p, :p], Rf[:p, p]


def least_squares_trf(fun, x0: np.ndarray, jac="2-point", bounds=(-np.inf, np.inf), *,
                      ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8,
                      x_scale="jac", diff_step: float | None = None,
                      max_nfev: int | None = None) -> OptimizeResult:
    """Minimise ½‖fun(x)‖² within ``bounds``, as ``scipy.optimize.least_squares(fun, x0,
    jac, bounds, method="trf", ...)`` (module docstring: the same steps on the QR factor).

    Parameters
    ----------
    fun : callable
        ``x -> f`` (m,) residuals.
    x0 : ndarray
        Start (p,), inside the bounds.
    jac : callable or "2-point"
        ``x -> J`` (m, p), or forward differences of ``fun`` with relative step
        ``diff_step`` that respect the bounds.
    bounds : (lb, ub)
        Scalars or (p,) arrays; ±inf where a parameter is unbounded.
    ftol, xtol, gtol, x_scale, max_nfev
        As ``least_squares`` (``x_scale``: "jac" or an array).

    Returns
    -------
    OptimizeResult
        ``x, cost, fun, grad, optimality, active_mask, nfev, njev, status, message,
        success`` as ``least_squares`` gives them; ``jac`` is R (p × p), whose RᵀR = JᵀJ at
        the solution, and ``m`` the number of residuals.
    """
    x0 = np.atleast_1d(np.asarray(x0, float))
    n = x0.size
    lb, ub = (np.broadcast_to(np.asarray(b, float), (n,)).copy() for b in bounds)
    if np.any(x0 < lb) or np.any(x0 > ub):
        raise ValueError("Initial guess is outside of provided bounds")
    if callable(jac):
        def jacobian(x, f):
            return np.atleast_2d(jac(x))
    else:
        def jacobian(x, f):
            return np.atleast_2d(approx_derivative(fun, x, method=jac, rel_step=diff_step,
                                                   f0=f, bounds=(lb, ub)))
    x = make_strictly_feasible(x0, lb, ub)
    f = np.atleast_1d(np.asarray(fun(x), float))
    if not np.all(np.isfinite(f)):
        raise ValueError("Residuals are not finite in the initial point.")
    m = f.size
    if max_nfev is None:
        max_nfev = n * 100
    R, qf = _factor(jacobian(x, f), f)
    nfev = njev = 1
    cost = 0.5 * np.dot(f, f)
    g = R.T.dot(qf)
    jac_scale = isinstance(x_scale, str) and x_scale == "jac"
    if jac_scale:
        scale, scale_inv = compute_jac_scale(R)
    else:
        scale = np.broadcast_to(np.asarray(x_scale, float), (n,))
        scale_inv = 1 / scale
    v, dv = CL_scaling_vector(x, g, lb, ub)
    v[dv != 0] *= scale_inv[dv != 0]
    Delta = norm(x * scale_inv / v**0.5)
    if Delta == 0:
        Delta = 1.0
    alpha = 0.0         # the Levenberg-Marquardt parameter
    status = None
    qf_aug = np.zeros(2 * n)
    A = np.empty((2 * n, n))
    while True:
        v, dv = CL_scaling_vector(x, g, lb, ub)
        g_norm = norm(g * v, ord=np.inf)
        if g_norm < gtol:
            status = 1
        if status is not None or nfev == max_nfev:
            break
        v[dv != 0] *= scale_inv[dv != 0]
        d = v**0.5 * scale
        diag_h = g * dv * scale
        g_h = d * g
        A[:n] = R * d
        R_h = A[:n]
        A[n:] = np.diag(diag_h**0.5)
        U, s, V = svd(A, full_matrices=False)
        V = V.T
        qf_aug[:n] = qf
        uf = U.T.dot(qf_aug)
        theta = max(0.995, 1 - g_norm)
        actual_reduction = -1
        while actual_reduction <= 0 and nfev < max_nfev:
            # m + n: the rows of scipy's augmented matrix, in its rank threshold
            p_h, alpha, _ = solve_lsq_trust_region(n, m + n, uf, s, V, Delta,
                                                   initial_alpha=alpha)
            p = d * p_h
            step, step_h, predicted_reduction = select_step(
                x, R_h, diag_h, g_h, p, p_h, d, Delta, lb, ub, theta)
            x_new = make_strictly_feasible(x + step, lb, ub, rstep=0)
            f_new = np.atleast_1d(np.asarray(fun(x_new), float))
            nfev += 1
            step_h_norm = norm(step_h)
            if not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * np.dot(f_new, f_new)
            actual_reduction = cost - cost_new
            Delta_new, ratio = update_tr_radius(Delta, actual_reduction, predicted_reduction,
                                                step_h_norm, step_h_norm > 0.95 * Delta)
            step_norm = norm(step)
            status = check_termination(actual_reduction, cost, step_norm, norm(x), ratio,
                                       ftol, xtol)
            if status is not None:
                break
            alpha *= Delta / Delta_new
            Delta = Delta_new
        if actual_reduction > 0:
            x, f, cost = x_new, f_new, cost_new
            R, qf = _factor(jacobian(x, f), f)
            njev += 1
            g = R.T.dot(qf)
            if jac_scale:
                scale, scale_inv = compute_jac_scale(R, scale_inv)
    if status is None:
        status = 0
    return OptimizeResult(
        x=x, cost=cost, fun=f, jac=R, m=m, grad=g, optimality=g_norm,
        active_mask=find_active_constraints(x, lb, ub, rtol=xtol), nfev=nfev, njev=njev,
        status=status, message=TERMINATION_MESSAGES[status], success=status > 0)
