"""Compiled inner loop of the structured H∞ tuning: σ̄ of the weighted closed loop.

For every model i and frequency k, with K and G the 2×2 responses there:
S = (I + G K)⁻¹, X = [W_p S; −W_u K S] (4×2), Y = [I, W_d G] (2×4) and
σ̄(X·Y)² = λ_max(XᴴX·YYᴴ) — a product of two Hermitian 2×2 matrices, in closed form.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _a2(z):  # pragma: no cover - compiled
    return z.real * z.real + z.imag * z.imag


@numba.njit(cache=True)
def weighted_sigma(K, G, y11, y12, y22, wp2, wu2, out, out_s):  # pragma: no cover - compiled
    """out[i, k] = σ̄(F_l(P_i, K)) and out_s[i, k] = σ̄(S_o) at frequency k.

    Parameters
    ----------
    K : complex (n_f, 2, 2)
    G : complex (n_models, n_f, 2, 2)
    y11, y22 : float (n_models, n_f); y12 : complex (n_models, n_f)
        YYᴴ = I + W_d² G Gᴴ.
    wp2, wu2 : float (n_f,)
        |W_p|², |W_u|².
    out, out_s : float (n_models, n_f)
    """
    nm, nf = G.shape[0], G.shape[1]
    for i in range(nm):
        for k in range(nf):
            k11, k12, k21, k22 = K[k, 0, 0], K[k, 0, 1], K[k, 1, 0], K[k, 1, 1]
            g11, g12, g21, g22 = G[i, k, 0, 0], G[i, k, 0, 1], G[i, k, 1, 0], G[i, k, 1, 1]
            a = 1 + g11 * k11 + g12 * k21
            b = g11 * k12 + g12 * k22
            c = g21 * k11 + g22 * k21
            d = 1 + g21 * k12 + g22 * k22
            inv = 1.0 / (a * d - b * c)
            s11, s12, s21, s22 = d * inv, -b * inv, -c * inv, a * inv
            fro = _a2(s11) + _a2(s12) + _a2(s21) + _a2(s22)
            ds = _a2(inv)
            dd = fro * fro - 4.0 * ds
            out_s[i, k] = np.sqrt(0.5 * (fro + np.sqrt(dd if dd > 0.0 else 0.0)))
            q11 = k11 * s11 + k12 * s21
            q12 = k11 * s12 + k12 * s22
            q21 = k21 * s11 + k22 * s21
            q22 = k21 * s12 + k22 * s22
            h11 = wp2[k] * (_a2(s11) + _a2(s21)) + wu2[k] * (_a2(q11) + _a2(q21))
            h22 = wp2[k] * (_a2(s12) + _a2(s22)) + wu2[k] * (_a2(q12) + _a2(q22))
            h12 = wp2[k] * (np.conj(s11) * s12 + np.conj(s21) * s22) \
                + wu2[k] * (np.conj(q11) * q12 + np.conj(q21) * q22)
            tr = h11 * y11[i, k] + h22 * y22[i, k] + 2.0 * (h12 * np.conj(y12[i, k])).real
            dt = (h11 * h22 - _a2(h12)) * (y11[i, k] * y22[i, k] - _a2(y12[i, k]))
            disc = tr * tr - 4.0 * dt
            lam = 0.5 * (tr + np.sqrt(disc if disc > 0.0 else 0.0))
            out[i, k] = np.sqrt(lam if lam > 0.0 else 0.0)
