"""Signature regression: the residual regressed on an effect's regressors, scored out of sample.

:class:`SignatureFit` (score, coefficients, F-test p-value), :func:`signature_fit` and the
effective sample size :func:`effective_n` of an autocorrelated residual. Re-exported by
:mod:`rigd.effects.base`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .context import Context


# --------------------------------------------------------------------------------------
# signature regression
# --------------------------------------------------------------------------------------
@dataclass
class SignatureFit:
    """Result of regressing the residual on an effect's regressors.

    ``score`` is 1 − ‖r_val − Φ_val β‖² / ‖r_val‖² clipped to [0, 1] (out of sample), ``f_p``
    the p-value of the F test on the estimation part with an effective sample size
    corrected for the residual's autocorrelation.
    """

    score: float
    beta: np.ndarray
    f_p: float
    k: int
    score_est: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def _weights(ctx: Context) -> np.ndarray:
    """Per-output weights 1/std(y) so that every output counts alike (as the mean fit)."""
    s = np.std(ctx.y[ctx.est], axis=0)
    s[s == 0] = 1.0
    return 1.0 / s


def effective_n(r: np.ndarray, max_lag: int = 200) -> float:
    """Effective number of independent samples of a (n,) series (Bartlett's formula)."""
    r = r - r.mean()
    n = r.shape[0]
    if n < 4 or not np.any(r):
        return float(n)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(r, nfft)
    ac = np.fft.irfft(f * np.conj(f), nfft)[:min(max_lag, n - 1) + 1]
    rho = ac / ac[0]
    # sum until the first non-positive value (initial positive sequence)
    stop = np.argmax(rho[1:] <= 0) + 1 if np.any(rho[1:] <= 0) else len(rho)
    tau = 1.0 + 2.0 * np.sum(rho[1:stop])
    return float(n / max(tau, 1.0))


def signature_fit(ctx: Context, regs: Sequence[np.ndarray], ridge: float = 1e-9) -> SignatureFit:
    """Least-squares fit of the (weighted, stacked) residual on the regressors."""
    from scipy import stats

    if not regs:
        return SignatureFit(0.0, np.zeros(0), 1.0, 0)
    w = _weights(ctx)
    r = ctx.residual * w
    Phi = np.stack([np.asarray(g, float) * w for g in regs], axis=-1)  # (n, ny, k)
    k = Phi.shape[-1]
    if not np.all(np.isfinite(Phi)) or np.max(np.abs(Phi)) > 1e100:
        # a regressor from a diverging simulation (unstable extended model) carries no
        # signature
        return SignatureFit(0.0, np.zeros(k), 1.0, k)
    re, rv = r[ctx.est].reshape(-1), r[ctx.val].reshape(-1)
    Pe, Pv = Phi[ctx.est].reshape(-1, k), Phi[ctx.val].reshape(-1, k)
    scale = np.sqrt(np.sum(Pe ** 2, axis=0))
    scale[scale == 0] = 1.0
    A = Pe / scale
    beta_s = np.linalg.solve(A.T @ A + ridge * np.eye(k), A.T @ re)
    beta = beta_s / scale
    e_est = re - Pe @ beta
    e_val = rv - Pv @ beta
    ss0_e, ss0_v = float(re @ re), float(rv @ rv)
    score = 0.0 if ss0_v == 0 else max(0.0, 1.0 - float(e_val @ e_val) / ss0_v)
    score_est = 0.0 if ss0_e == 0 else max(0.0, 1.0 - float(e_est @ e_est) / ss0_e)
    # F test with effective n from the autocorrelation of the estimation residual
    neff = min(effective_n(ctx.residual[ctx.est, i]) for i in range(ctx.ny)) * ctx.ny
    dof = max(neff - k, 1.0)
    sse = max(float(e_est @ e_est), 1e-300)
    F = ((ss0_e - sse) / k) / (sse / dof)
    p = float(stats.f.sf(max(F, 0.0), k, dof))
    return SignatureFit(score, beta, p, k, score_est)
