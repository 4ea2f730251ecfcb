"""Subspace identification (PO-MOESP with a state-sequence regression, Verhaegen 1994 /
Van Overschee & De Moor 1996): a non-iterative discrete-time model of any order, any number
of inputs and outputs, in innovation form (A, B, C, D, K, x0) — a black-box reference.

Steps, on channels scaled to zero mean and unit standard deviation (the result does not
depend on units; it is returned in the record's units):

1. the block-Hankel data [U_f; U_p; Y_p; Y_f] (``horizon`` block rows each) enter an LQ
   decomposition accumulated chunk by chunk (:func:`~rigd.ident.lti.lsq.stacked_r`): memory
   (2·horizon·(nu + ny))², never an N × N matrix;
2. the SVD of L₃₂ (future outputs given the past, the future inputs' part removed) gives the
   extended observability matrix Γ and the singular values from which the order is read;
3. the state sequence X = Γ⁺ L₃₂ L₂₂⁺ W_p (W_p the past data) is regressed:
   [x(t+1); y(t)] = [A B; C D] [x(t); u(t)]; the residuals give K (least squares, or the
   Kalman gain from their covariances when that predictor would be unstable);
4. with A stable, B, D and x0 are re-estimated by least squares on the simulated output
   (MOESP's output-error step) when that fits the data better.

It supersedes the former ``rigd.ident.subspace.n4sid_a`` (A and C only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rigd.ident.figures import fit_percent
from rigd.ident.lti.linear import LinearModel, as_2d, free_responses
from rigd.ident.lti.lsq import solve_r, stacked_r

#: largest order considered by ``order="auto"``
MAX_ORDER = 30
#: ``order="auto"``: a singular value counts as a state above this multiple of the noise floor
SV_FLOOR_RATIO = 10.0


@dataclass
class SubspaceResult:
    """Result of :func:`n4sid`.

    Attributes
    ----------
    model : LinearModel
        A, B, C, D, K, x0 (state at the first sample), operating point (the data's means).
    sv : ndarray
        Singular values of L₃₂ (scaled data), largest first: the order selection aid.
    order : int
        Number of states of ``model``.
    horizon : int
        Block rows used.
    """

    model: LinearModel
    sv: np.ndarray
    order: int
    horizon: int


def default_horizon(n: int, nu: int, ny: int, order: int) -> int:
    """Block rows for an estimate up to ``order`` states from n samples: 2·(order + 1)/ny
    (at least 20), fewer when the record is short (at least ⌊order/ny⌋ + 1)."""
    want = max(20, -(-2 * (order + 1) // ny))
    room = (n + 1) // (2 + 4 * (nu + ny))
    return int(max(order // ny + 1, min(want, room)))


def order_from_sv(sv: np.ndarray, max_order: int) -> int:
    """Number of singular values above :data:`SV_FLOOR_RATIO` × the noise floor (the median
    of those from ``max_order``/2 to ``max_order``), at most ``max_order``, at least 1."""
    s = np.asarray(sv, float)
    tail = s[max_order // 2:max(max_order, max_order // 2 + 2)]
    floor = float(np.median(tail)) if tail.size else 0.0
    return int(min(max_order, max(1, np.count_nonzero(s[:max_order] > SV_FLOOR_RATIO * floor))))


def _hankel_rows(signals, horizon):
    """rows(c0, c1): per column c of the block-Hankel data, the samples c … c + horizon − 1
    of each (n, m) signal (offset) in ``signals``, side by side (time-major)."""
    def rows(c0, c1):
        out = []
        for s, off in signals:
            out += [s[c0 + off + k:c1 + off + k] for k in range(horizon)]
        return np.hstack(out)
    return rows


def _kalman_gain(A, C, W, V):
    """Innovation gain from the state and output residuals (rows: samples)."""
    n = len(W)
    K = np.linalg.lstsq(V, W, rcond=None)[0].T if A.size else np.zeros((0, V.shape[1]))
    if A.size == 0 or np.max(np.abs(np.linalg.eigvals(A - K @ C))) < 1.0:
        return K
    cov = np.cov(np.hstack([W, V]).T) if n > 1 else None
    nx = A.shape[0]
    Q, S, R = cov[:nx, :nx], cov[:nx, nx:], cov[nx:, nx:]
    try:
        P = scipy.linalg.solve_discrete_are(A.T, C.T, Q, R, s=S)
        return (A @ P @ C.T + S) @ np.linalg.inv(C @ P @ C.T + R)
    except (np.linalg.LinAlgError, ValueError):
        return np.zeros_like(K)


def _refine_bd(A, C, du, dy):
    """B, D, x0 by least squares on the free-run output, given A and C (scaled data)."""
    from rigd.ident.sim_kernels import lsim_kernel

    n, nu = du.shape
    ny, nx = C.shape
    # resp[b, a]: output (n, ny) of input b entering state a alone (B = e_a)
    resp = np.empty((nu, nx, n, ny))
    zero = np.zeros(nx)
    for b in range(nu):
        ub = np.ascontiguousarray(du[:, b:b + 1])
        for a in range(nx):
            e = np.zeros((nx, 1))
            e[a] = 1.0
            lsim_kernel(A, e, C, zero, ub, resp[b, a])
    G = free_responses(A, C, n)   # C A^t: free response of each initial state
    d = nx * nu + ny * nu + nx

    def rows(t0, t1):
        m = t1 - t0
        reg = np.zeros((m, ny, d))
        for b in range(nu):
            reg[:, :, b * nx:(b + 1) * nx] = np.moveaxis(resp[b, :, t0:t1], 0, 2)
            for ch in range(ny):
                reg[:, ch, nx * nu + ch * nu + b] = du[t0:t1, b]
        reg[:, :, nx * nu + ny * nu:] = G[t0:t1]
        return np.hstack([reg.reshape(m * ny, d), dy[t0:t1].reshape(m * ny, 1)])

    theta = solve_r(stacked_r(rows, n, d + 1, chunk=max(256, 8192 // ny)), d)[:, 0]
    B = theta[:nx * nu].reshape(nu, nx).T
    D = theta[nx * nu:nx * nu + ny * nu].reshape(ny, nu)
    return B, D, theta[nx * nu + ny * nu:]


def n4sid(u: np.ndarray, y: np.ndarray, order: int | str = "auto",
          horizon: int | None = None, max_order: int = MAX_ORDER, fs: float | None = None,
          feedthrough: bool = True) -> SubspaceResult:
    """Subspace estimate of a discrete-time model of u → y (module docstring).

    Parameters
    ----------
    u, y : ndarray (n,) or (n, nu), (n,) or (n, ny)
        Estimation data, any units.
    order : int or "auto"
        Number of states, or ``"auto"``: :func:`order_from_sv` up to ``max_order``.
    horizon : int, optional
        Block rows (default: enough for ``max_order`` or ``order``, ≥ 10).
    fs : float, optional
        Sample rate (Hz), kept for readouts.
    feedthrough : bool
        Estimate D (else D = 0).
    """
    top = max_order if order == "auto" else int(order)
    if top < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    dec = _Decomposition(u, y, top, horizon, fs, feedthrough)
    sv = dec.sv
    nx = order_from_sv(sv, min(max_order, len(sv) - 1)) if order == "auto" else int(order)
    return SubspaceResult(dec.model(nx), sv, nx, dec.i)


def dynamics_matrices(u: np.ndarray, y: np.ndarray, requests) -> list[np.ndarray | None]:
    """The discrete A of ``n4sid(u, y, order, horizon=horizon).model`` for each
    ``(order, horizon)`` of ``requests`` (``horizon`` None: :func:`default_horizon` for that
    order), the same matrices, from one decomposition per distinct horizon and without the
    B, D, K, x0 steps; None where the record or horizon cannot support the order."""
    u, y = as_2d(u), as_2d(y)
    n, nu = u.shape
    ny = y.shape[1]
    decs: dict[int, _Decomposition | None] = {}
    out: list[np.ndarray | None] = []
    for order, horizon in requests:
        i = int(horizon or default_horizon(n, nu, ny, int(order)))
        if i not in decs:
            try:
                decs[i] = _Decomposition(u, y, int(order), i, None, True)
            except (ValueError, np.linalg.LinAlgError):
                decs[i] = None
        try:
            out.append(None if decs[i] is None else decs[i].dynamics(int(order))[1])
        except (ValueError, np.linalg.LinAlgError):
            out.append(None)
    return out


def clamp_poles(A: np.ndarray) -> np.ndarray:
    """``A`` with every eigenvalue outside the unit circle moved onto it (same angle); ``A``
    itself when none is (or it cannot be diagonalised)."""
    lam, V = np.linalg.eig(A)
    r = np.abs(lam)
    if not np.any(r > 1.0):
        return A
    lam = np.where(r > 1.0, lam / np.maximum(r, 1e-300), lam)
    try:
        out = V @ np.diag(lam) @ np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return A
    return np.ascontiguousarray(out.real) if np.all(np.isfinite(out)) else A


class _Decomposition:
    """Steps 1–2 of the module docstring (LQ and SVD, shared by every order) and
    :meth:`model` (steps 3–4 for one order)."""

    def __init__(self, u, y, top, horizon, fs, feedthrough):
        u, y = as_2d(u), as_2d(y)
        n, nu = u.shape
        ny = y.shape[1]
        i = self.i = int(horizon or default_horizon(n, nu, ny, top))
        self.u0, self.y0 = u.mean(0), y.mean(0)
        self.su, self.sy = np.maximum(u.std(0), 1e-300), np.maximum(y.std(0), 1e-300)
        self.du, self.dy = (u - self.u0) / self.su, (y - self.y0) / self.sy
        j = self.j = n - 2 * i + 1
        r1, r2, r3 = i * nu, i * (nu + ny), i * ny
        if j < 2 * (r1 + r2 + r3):
            raise ValueError(f"record too short for a subspace estimate with horizon {i} "
                             f"({n} samples)")
        R = stacked_r(_hankel_rows([(self.du, i), (self.du, 0), (self.dy, 0), (self.dy, i)],
                                   i), j, r1 + r2 + r3)
        L = R.T
        self.L22 = L[r1:r1 + r2, r1:r1 + r2]
        self.L32 = L[r1 + r2:, r1:r1 + r2]
        self.U1, self.sv, _ = np.linalg.svd(self.L32, full_matrices=False)
        self.fs, self.feedthrough, self.r3 = fs, feedthrough, r3
        # the state-sequence step's pseudo-inverse and past data: built on the first model()
        # (the dynamics alone, :meth:`dynamics`, need neither)
        self._L22p: np.ndarray | None = None
        self._Wp: np.ndarray | None = None

    @property
    def L22p(self) -> np.ndarray:
        """Pseudo-inverse of L₂₂ (built once)."""
        if self._L22p is None:
            self._L22p = np.linalg.pinv(self.L22, rcond=1e-10)
        return self._L22p

    @property
    def Wp(self) -> np.ndarray:
        """(j, r2) past data of the block-Hankel matrix (built once)."""
        if self._Wp is None:
            self._Wp = _hankel_rows([(self.du, 0), (self.dy, 0)], self.i)(0, self.j)
        return self._Wp

    def dynamics(self, nx: int) -> tuple[np.ndarray, np.ndarray]:
        """(Γ, A) of order ``nx`` (scaled data): the extended observability matrix and the
        discrete dynamics by its shift invariance — the A of :meth:`model` (``stabilise``
        False) without the B, D, K, x0 steps."""
        ny = self.dy.shape[1]
        if not 1 <= nx < self.r3:
            raise ValueError(f"order {nx} needs 1 <= order < horizon·outputs ({self.r3})")
        Gam = self.U1[:, :nx] * np.sqrt(self.sv[:nx])   # extended observability
        return Gam, np.linalg.lstsq(Gam[:-ny], Gam[ny:], rcond=None)[0]

    def model(self, nx: int, refine: bool = True, stabilise: bool = False) -> LinearModel:
        """The order-``nx`` model in the record's units (``refine``: step 4, B, D and x0 by
        least squares on the free-run output; ``stabilise``: poles outside the unit circle
        brought onto it first (:func:`clamp_poles`: closed-loop or short records can give an
        integrator's estimate just outside), so that step 4 applies)."""
        du, dy, i, j, fs = self.du, self.dy, self.i, self.j, self.fs
        nu, ny = du.shape[1], dy.shape[1]
        Gam, A = self.dynamics(nx)
        if stabilise:
            A = clamp_poles(A)
        C = Gam[:ny]
        Mx = np.linalg.pinv(Gam) @ self.L32 @ self.L22p      # X = Mx W_p
        X = self.Wp @ Mx.T                            # (j, nx): state at t = i + c
        t = np.arange(i, i + j - 1)
        # B, D (A and C fixed) from [x(t+1) − A x(t); y(t) − C x(t)] = [B; D] u(t)
        T = np.hstack([X[1:] - X[:-1] @ A.T, dy[t] - X[:-1] @ C.T])
        BD = np.linalg.lstsq(du[t], T, rcond=None)[0].T
        B = BD[:nx]
        D = BD[nx:] if self.feedthrough else np.zeros((ny, nu))
        res = T - du[t] @ np.vstack([B, D]).T
        K = _kalman_gain(A, C, res[:, :nx], res[:, nx:])
        m = LinearModel(A, B, C, D, K, np.zeros(nx), np.zeros(nu), np.zeros(ny), fs)
        m.fit_x0(du, dy)
        if refine and np.max(np.abs(np.linalg.eigvals(A))) <= 1.0 + 1e-9:
            try:
                B2, D2, x02 = _refine_bd(A, C, du, dy)
                if not self.feedthrough:
                    D2 = np.zeros_like(D2)
                alt = LinearModel(A, B2, C, D2, K, x02, m.u0, m.y0, fs)
                if np.mean(fit_percent(dy, alt.simulate(du))) > \
                        np.mean(fit_percent(dy, m.simulate(du))):
                    m = alt
            except (np.linalg.LinAlgError, ValueError):
                pass
        su, sy = self.su, self.sy      # back to the record's units
        return LinearModel(m.A, m.B / su, m.C * sy[:, None], m.D * sy[:, None] / su,
                           m.K / sy, m.x0, self.u0, self.y0, fs)


def select_subspace(u: np.ndarray, y: np.ndarray, orders=tuple(range(1, 21)),
                    fs: float | None = None) -> tuple[SubspaceResult, dict[int, float]]:
    """Subspace model with the order chosen on the estimation data (u, y) alone: each order
    is fitted on the first two thirds and scored by the free-run fit on the last third
    (:func:`~rigd.ident.lti.linear.heldout`); the best is refitted on all of (u, y) and kept
    when that refit is stable (else the next best order whose refit is). One decomposition
    serves every order (horizon for the largest).

    Returns the result and the check fit (%) of every order tried (−inf: diverged).
    """
    from rigd.ident.lti.linear import heldout

    u, y = as_2d(u), as_2d(y)
    cut = (2 * len(u)) // 3
    top = max(orders)
    scores: dict[int, float] = {}
    try:
        dec = _Decomposition(u[:cut], y[:cut], top, None, fs, True)
    except (ValueError, np.linalg.LinAlgError):
        dec = None
    for nx in orders if dec is not None else ():
        try:
            fit, _ = heldout(dec.model(nx), u, y, cut)
        except (ValueError, np.linalg.LinAlgError):
            continue
        scores[int(nx)] = float(np.mean(fit))
    if not scores:
        raise ValueError(f"record too short for any subspace order in {tuple(orders)} "
                         f"({len(u)} samples)")
    full = _Decomposition(u, y, top, None, fs, True)
    # the refit on all of (u, y) is checked again: the best check order whose refit is
    # stable (a refit can move a pole outside the unit circle); none: the best, its poles
    # brought onto the unit circle
    ranked = sorted(scores, key=lambda k: (-scores[k], k))
    for nx in ranked:
        if not np.isfinite(scores[nx]):
            break
        try:
            m = full.model(nx)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if m.stable():
            return SubspaceResult(m, full.sv, nx, full.i), scores
    best = ranked[0]
    return SubspaceResult(full.model(best, stabilise=True), full.sv, best, full.i), scores


def continuous_modes(A: np.ndarray, fs: float) -> list[tuple[float, float]]:
    """Oscillatory modes (f_n in Hz, ζ) of the discrete dynamics matrix ``A`` at rate ``fs``:
    complex pole pairs below 0.95·Nyquist with 0 < ζ < 1, slowest first."""
    out = []
    for z in np.linalg.eigvals(A):
        if z.imag <= 1e-9 or abs(z) <= 0:
            continue
        s = np.log(z) * fs
        wn = abs(s)
        zeta = -s.real / wn
        f = wn / (2 * np.pi)
        if 0 < zeta < 1 and f < 0.95 * fs / 2:
            out.append((float(f), float(zeta)))
    return sorted(out)
