"""A discrete-time linear model in innovation form, the common result of the black-box
reference estimators (:mod:`.arx`, :mod:`.subspace`), and the honest held-out figure.

    x[k+1] = A x[k] + B (u[k] − u0) + K e[k]
    y[k]   = C x[k] + D (u[k] − u0) + y0 + e[k]

``u0``/``y0`` are the operating point (the estimation part's means); ``K`` the one-step
predictor gain. Simulation and prediction run in the compiled kernels of
:mod:`rigd.ident.sim_kernels` (no per-sample Python).

The held-out protocol (:func:`heldout`) is the one every tool in the ``bench peers`` table
uses: the model is fitted on the estimation part, its state at the end of that part is the
predictor's (measured inputs and outputs of the estimation part only), and the validation
part is then simulated free-run from that state. Nothing of the validation outputs is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigd.ident.figures import fit_percent
from rigd.ident.sim_kernels import lsim_kernel, predict_kernel


def as_2d(x: np.ndarray) -> np.ndarray:
    """(n,) or (n, m) samples as a float (n, m) C-contiguous array."""
    x = np.asarray(x, dtype=float)
    return np.ascontiguousarray(x[:, None] if x.ndim == 1 else x)


@dataclass
class LinearModel:
    """Discrete-time innovation-form model (module docstring).

    Attributes
    ----------
    A, B, C, D, K : ndarray (nx, nx), (nx, nu), (ny, nx), (ny, nu), (nx, ny)
        In the record's units: inputs and outputs as given, one sample = one step.
    x0 : ndarray (nx,)
        State at the first sample of the data the model was estimated on.
    u0, y0 : ndarray (nu,), (ny,)
        Operating point subtracted from the inputs / added to the outputs.
    fs : float or None
        Sample rate (Hz), for readouts only.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    K: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    y0: np.ndarray
    fs: float | None = None

    @property
    def order(self) -> int:
        """Number of states."""
        return int(self.A.shape[0])

    def poles(self) -> np.ndarray:
        """Discrete poles (eigenvalues of A)."""
        return np.linalg.eigvals(self.A) if self.order else np.zeros(0, complex)

    def stable(self) -> bool:
        """True when every pole is strictly inside the unit circle."""
        return bool(self.order == 0 or np.max(np.abs(self.poles())) < 1.0)

    def dc_gain(self) -> np.ndarray:
        """(ny, nu) static gain C (I − A)⁻¹ B + D (inf where A has a pole at 1)."""
        n = self.order
        try:
            return self.C @ np.linalg.solve(np.eye(n) - self.A, self.B) + self.D
        except np.linalg.LinAlgError:
            return np.full(self.D.shape, np.inf)

    def simulate(self, u: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Free-run output (n, ny) for the inputs ``u`` (n, nu) from state ``x0``
        (default: :attr:`x0`)."""
        du = as_2d(u) - self.u0
        x = np.asarray(self.x0 if x0 is None else x0, float).copy()
        y = np.empty((du.shape[0], self.C.shape[0]))
        lsim_kernel(self.A, self.B, self.C, x, du, y)
        return y + du @ self.D.T + self.y0

    def _filter(self, u, y, x0, extra_rows):
        du = as_2d(u) - self.u0
        dy = as_2d(y) - self.y0 - du @ self.D.T
        x = np.asarray(self.x0 if x0 is None else x0, float).copy()
        C = np.vstack([self.C, extra_rows]) if extra_rows is not None else self.C
        K = self.K
        meas = dy
        if extra_rows is not None:  # extra outputs (the state) with a zero gain: no feedback
            meas = np.hstack([dy, np.zeros((du.shape[0], extra_rows.shape[0]))])
            K = np.hstack([self.K, np.zeros((self.order, extra_rows.shape[0]))])
        out = np.empty((du.shape[0], C.shape[0]))
        predict_kernel(self.A, self.B, np.ascontiguousarray(K), np.ascontiguousarray(C), x,
                       np.ascontiguousarray(du), np.ascontiguousarray(meas), out)
        return du, dy, out

    def predict(self, u: np.ndarray, y: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """One-step-ahead prediction (n, ny) of ``y`` from the measured u and y."""
        du, _, out = self._filter(u, y, x0, None)
        return out + du @ self.D.T + self.y0

    def end_state(self, u: np.ndarray, y: np.ndarray, x0: np.ndarray | None = None
                  ) -> np.ndarray:
        """The predictor's state after the last sample of (u, y): the state from which the
        next samples are simulated in :func:`heldout`."""
        n = self.order
        if n == 0 or len(u) == 0:
            return np.asarray(self.x0 if x0 is None else x0, float).copy()
        du, dy, out = self._filter(u, y, x0, np.eye(n))
        ny = self.C.shape[0]
        x_last = out[-1, ny:]
        e = dy[-1] - out[-1, :ny]
        return self.A @ x_last + self.B @ du[-1] + self.K @ e

    def fit_x0(self, u: np.ndarray, y: np.ndarray, n_fit: int | None = None) -> np.ndarray:
        """Least-squares initial state for a free run of (u, y) over the first ``n_fit``
        samples (default min(n, 20·nx + 200)); stores and returns it."""
        n = self.order
        if n == 0:
            return self.x0
        m = min(len(u), n_fit or 20 * n + 200)
        y_free = self.simulate(u[:m], np.zeros(n))
        obs = free_responses(self.A, self.C, m)  # C A^k: free response of each initial state
        obs[~np.isfinite(obs)] = 0.0
        resid = (as_2d(y)[:m] - y_free).reshape(-1)
        self.x0 = np.linalg.lstsq(obs.reshape(-1, n), resid, rcond=None)[0]
        return self.x0


def free_responses(A: np.ndarray, C: np.ndarray, n: int) -> np.ndarray:
    """(n, ny, nx): C A^t, the free response of each unit initial state over n samples (the
    compiled simulation kernel, one run per state)."""
    nx, ny = A.shape[0], C.shape[0]
    G = np.empty((n, ny, nx))
    zb, zu = np.zeros((nx, 1)), np.zeros((n, 1))
    out = np.empty((n, ny))
    A, C = np.ascontiguousarray(A, float), np.ascontiguousarray(C, float)
    for a in range(nx):
        e = np.zeros(nx)
        e[a] = 1.0
        with np.errstate(all="ignore"):
            lsim_kernel(A, zb, C, e, zu, out)
        G[:, :, a] = out
    return G


def heldout(model: LinearModel, u: np.ndarray, y: np.ndarray, n_est: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """Held-out free-run fit of ``model`` on samples ``n_est:`` of (u, y).

    The state at sample ``n_est`` is the predictor's after the estimation part
    (:meth:`LinearModel.end_state`, from :attr:`LinearModel.x0`); the validation part is then
    simulated without its outputs.

    Returns
    -------
    fit : ndarray (ny,)
        ``fit_percent`` per output on the validation part (%).
    yhat : ndarray (n − n_est, ny)
        The simulated validation outputs.
    """
    u, y = as_2d(u), as_2d(y)
    x = model.end_state(u[:n_est], y[:n_est])
    with np.errstate(all="ignore"):
        yhat = model.simulate(u[n_est:], x)
    fit = fit_percent(y[n_est:], yhat)
    return np.where(np.isfinite(fit), fit, -np.inf), yhat
