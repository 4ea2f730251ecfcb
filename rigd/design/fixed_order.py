"""Fixed-order K∞ parametrisation for structured H∞ tuning (:mod:`rigd.design.structured`).

A 2×2 controller of ``n`` states, K∞(s) = C (sI − A)⁻¹ B + D, written in a frequency-scaled
time unit s' = s/ω_s (ω_s = :data:`rigd.design.hinf.OMEGA_SCALE`, 2π·100 Hz) so that every
entry is of order one:

* **A** is real block-diagonal: one 2×2 block per pole pair,
  ``[[0, ω_n], [−ω_n, −2ζω_n]]`` with ω_n = e^{p}, ζ = e^{q} (characteristic polynomial
  λ² + 2ζω_n λ + ω_n²: stable by construction for every parameter value, real or complex
  poles; the entries stay of the size of ω_n, unlike a companion form), plus one real pole
  −e^{p} when ``n`` is odd;
* **B** (n×2) is free;
* **C** = Ĉ·P with Ĉ (2×n) free and P the orthogonal projector onto the left null space of
  M = [A⁻ᵏB, …]: this puts an ``m``-fold zero at s = 0 on every element of K (the paper's
  "controller not active at DC", Fig. 5; :class:`rigd.design.weights.HighPass` ``order`` = m),
  exactly, for every parameter value. K(s) = D − Σ_k sᵏ C A^{−(k+1)} B, so the zero needs
  C A^{−(k+1)} B = 0 for k < m: strictly proper (D = 0) takes M = [A⁻¹B … A⁻ᵐB] (2m columns,
  needs n ≥ 2m + 2 for a rank-2 C); otherwise (fewer states) K is proper with
  D = C A⁻¹ B and M = [A⁻²B … A⁻ᵐB] (2m − 2 columns). The projector is a smooth function of
  the parameters (a null-space basis from an SVD is not), which the finite-difference
  gradients need.

The parameter vector is ``x = [p_1, q_1, …, vec(B), vec(Ĉ)]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigd.design.hinf import OMEGA_SCALE


@dataclass(frozen=True)
class FixedOrder:
    """Structure of a fixed-order 2×2 K∞ (see module docstring).

    Attributes
    ----------
    n : int
        Number of states (the deployed controller order).
    m : int
        Zeros at s = 0 on every element (0: none).
    ny, nu : int
        Controller inputs (measured e = −p, µm) and outputs (valve references r, V).
    """

    n: int
    m: int = 2
    ny: int = 2
    nu: int = 2

    @property
    def strictly_proper(self) -> bool:
        return self.n >= self.nu * self.m + 2 if self.m else True

    @property
    def n_pairs(self) -> int:
        return self.n // 2

    @property
    def n_params(self) -> int:
        return 2 * self.n_pairs + (self.n % 2) + self.n * self.ny + self.nu * self.n

    def feasible(self) -> str | None:
        """Why this structure cannot carry a non-zero controller, or None."""
        if self.n < 1:
            return "the controller needs at least one state"
        k = self.ny * (self.m if self.strictly_proper else max(self.m - 1, 0))
        if self.n - k < 1:
            return (f"{self.n} states cannot hold {self.m} zeros at DC on a "
                    f"{self.nu}x{self.ny} controller (needs at least {k + 1})")
        return None

    # --- parameters -> matrices (scaled time unit) --------------------------------------
    def A(self, x: np.ndarray) -> np.ndarray:
        n = self.n
        A = np.zeros((n, n))
        for i in range(self.n_pairs):
            wn, zeta = np.exp(x[2 * i]), np.exp(x[2 * i + 1])
            A[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[0.0, wn], [-wn, -2.0 * zeta * wn]]
        if n % 2:
            A[-1, -1] = -np.exp(x[2 * self.n_pairs])
        return A

    def matrices(self, x: np.ndarray):
        """(A, B, C, D) of K∞ in the scaled time unit s' = s/ω_s."""
        x = np.asarray(x, float)
        n, ny, nu = self.n, self.ny, self.nu
        k0 = 2 * self.n_pairs + (n % 2)
        A = self.A(x)
        B = x[k0:k0 + n * ny].reshape(n, ny)
        Ch = x[k0 + n * ny:].reshape(nu, n)
        if not self.m:
            return A, B, Ch, np.zeros((nu, ny))
        Ainv_B = [np.linalg.solve(A, B)]
        for _ in range(self.m):
            Ainv_B.append(np.linalg.solve(A, Ainv_B[-1]))
        cols = Ainv_B[:self.m] if self.strictly_proper else Ainv_B[1:self.m]
        if cols:
            M = np.hstack(cols)
            P = np.eye(n) - M @ np.linalg.pinv(M)
        else:
            P = np.eye(n)
        C = Ch @ P
        D = np.zeros((nu, ny)) if self.strictly_proper else C @ Ainv_B[0]
        return A, B, C, D

    def response(self, x: np.ndarray, s: np.ndarray) -> np.ndarray:
        """K(s') (len(s), nu, ny) at complex points ``s`` of the scaled unit, block by block:
        for a block [[0, ω], [−ω, −2ζω]], (sI − A)⁻¹ = [[s + 2ζω, ω], [−ω, s]]/(s² + 2ζωs + ω²).
        """
        A, B, C, D = self.matrices(x)
        out = np.broadcast_to(D.astype(complex), (len(s),) + D.shape).copy()
        for i in range(self.n_pairs):
            j = slice(2 * i, 2 * i + 2)
            w, a22 = A[2 * i, 2 * i + 1], A[2 * i + 1, 2 * i + 1]
            det = s * (s - a22) + w * w
            Cb, Bb = C[:, j], B[j, :]
            # Cb @ [[s − a22, w], [−w, s]] @ Bb / det
            r0 = np.multiply.outer(s - a22, Bb[0]) + w * Bb[1][None, :]
            r1 = -w * Bb[0][None, :] + np.multiply.outer(s, Bb[1])
            out += (Cb[None, :, 0:1] * r0[:, None, :] + Cb[None, :, 1:2] * r1[:, None, :]) \
                / det[:, None, None]
        if self.n % 2:
            out += np.multiply.outer(1.0 / (s - A[-1, -1]), np.outer(C[:, -1], B[-1]))
        return out

    def ss(self, x: np.ndarray):
        """Continuous K∞(s) (python-control, rad/s)."""
        import control

        A, B, C, D = self.matrices(x)
        w = OMEGA_SCALE
        return control.ss(A * w, B * w, C, D)

    def pack(self, A_blocks: list[tuple[float, float]], real_pole: float | None,
             B: np.ndarray, Ch: np.ndarray) -> np.ndarray:
        """Parameter vector from pole pairs (ω_n, ζ) in the scaled unit, B and Ĉ."""
        x = []
        for wn, zeta in A_blocks:
            x += [np.log(wn), np.log(zeta)]
        if self.n % 2:
            x.append(np.log(real_pole))
        return np.concatenate([np.asarray(x, float), np.ravel(B), np.ravel(Ch)])


def freq_response(A, B, C, D, s: np.ndarray) -> np.ndarray:
    """K(s) (len(s), nu, ny) of a small state-space model at complex points ``s``."""
    n = A.shape[0]
    M = s[:, None, None] * np.eye(n)[None] - A[None]
    X = np.linalg.solve(M, np.broadcast_to(B, (len(s),) + B.shape).astype(complex))
    return C[None] @ X + D[None]
