"""Automatic initial guesses for mechanical structures from an empirical frequency response.

No previous model needed: the frequency response H(jω) (ny × nu per frequency) is estimated
from the data by Welch averaging (H1 estimator, :func:`frf`), corrected for the zero-order
hold, and the mass-normalised K, D, B of ``p̈ + D ṗ + K p = B u`` are fitted to it by linear
least squares on the equation error (Levy's method)::

    (K + jω D - ω² I) H(jω) = B        for every frequency with input power and coherence,

weighted by the multiple coherence, followed by a few Sanathanan-Koerner re-weightings
(divide by |det(K + jωD - ω²I)| of the previous estimate) that remove Levy's high-frequency
bias. Fixed-zero entries (decoupled actuator, Eqs. 8-10) are simply left out of the fit.
A result with unstable poles is made stable (negative stiffness reflected, damping added).
"""

from __future__ import annotations

import numpy as np


def frf(u: np.ndarray, y: np.ndarray, fs: float, nperseg: int | None = None):
    """Empirical frequency response by Welch averaging (H1 estimator).

    Parameters
    ----------
    u : ndarray (n, nu)
    y : ndarray (n, ny)
    fs : float
        Sample rate, Hz.
    nperseg : int, optional
        Segment length (default: a power of two near n/8, within 256..8192).

    Returns
    -------
    f : ndarray (nf,)
        Frequencies, Hz (DC excluded).
    H : ndarray (nf, ny, nu), complex
        H(f) = S_yu S_uu⁻¹.
    coh : ndarray (nf, ny)
        Multiple coherence of each output with all inputs (0..1).
    suu : ndarray (nf, nu)
        Input auto-spectra (power per bin, arbitrary scale).
    """
    u = np.atleast_2d(np.asarray(u, float).T).T
    y = np.atleast_2d(np.asarray(y, float).T).T
    n = u.shape[0]
    if nperseg is None:
        nperseg = int(2 ** np.clip(np.floor(np.log2(max(n / 8, 2))), 8, 13))
    nperseg = min(nperseg, n)
    step = nperseg // 2
    starts = np.arange(0, n - nperseg + 1, step)
    win = np.hanning(nperseg)
    X = np.concatenate([u, y], axis=1)
    X = X - X.mean(axis=0)
    segs = np.stack([X[s:s + nperseg] for s in starts])  # (nseg, nperseg, nc)
    F = np.fft.rfft(segs * win[None, :, None], axis=1)  # (nseg, nf, nc)
    S = np.einsum("kfa,kfb->fab", F, F.conj()) / len(starts)  # (nf, nc, nc)
    nu = u.shape[1]
    Suu = S[:, :nu, :nu]
    Syu = S[:, nu:, :nu]
    Syy = S[:, nu:, nu:]
    f = np.fft.rfftfreq(nperseg, 1.0 / fs)
    keep = f > 0
    f, Suu, Syu, Syy = f[keep], Suu[keep], Syu[keep], Syy[keep]
    Suu_inv = np.linalg.pinv(Suu)
    H = Syu @ Suu_inv
    explained = np.real(np.einsum("fia,fab,fib->fi", H, Suu, H.conj()))
    syy = np.real(np.einsum("fii->fi", Syy))
    coh = np.clip(explained / np.maximum(syy, 1e-300), 0.0, 1.0)
    suu = np.real(np.einsum("fii->fi", Suu))
    return f, H, coh, suu


def _damped(K: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, bool]:
    """D with extra diagonal damping until p̈ + D ṗ + K p = 0 is stable (60 steps at most);
    and whether it is."""
    n = K.shape[0]
    D = np.array(D, float)
    scale = np.sqrt(max(np.max(np.abs(np.diag(K))), 1e-12))
    for _ in range(60):
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -D]])
        if np.max(np.linalg.eigvals(A).real) < 0:
            return D, True
        D = D + np.eye(n) * 0.02 * scale
    return D, False


def stabilise(K: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, D) of a stable p̈ + D ṗ + K p = 0 near the given one.

    Diagonal damping is added until the system is stable. A negative stiffness (a real pole in
    the right half plane, which no damping moves) is then reflected, λ(K) → |Re λ| (as the
    pole reflection of MATLAB's initial estimates), and damping added again. A free mass with
    friction measured in a position loop gave K ≈ −250 s⁻² from the frequency response; the
    OE fit never left that unstable start (the fit diverged).
    """
    K = np.array(K, float)
    D2, ok = _damped(K, D)
    if ok:
        return K, D2
    lam, V = np.linalg.eig(K)
    try:
        K = np.real(V @ np.diag(np.abs(lam.real) + 1j * lam.imag) @ np.linalg.inv(V))
    except np.linalg.LinAlgError:
        K = K + np.eye(K.shape[0]) * 2.0 * max(-float(np.min(lam.real)), 0.0)
    return K, _damped(K, D)[0]


def levy_fit(f, H, coh, suu, fs, mask_K, mask_D, mask_B, iters: int = 4, hold: str = "zoh"):
    """Fit mass-normalised K, D, B to a frequency response (see module docstring).

    ``mask_*`` are boolean arrays of the free entries; the others stay zero.
    """
    nf, ny, nu = H.shape
    w = 2 * np.pi * f
    T = 1.0 / fs
    # undo the half-sample delay and sinc droop of the zero-order hold (none for FOH)
    Hc = H * (np.exp(1j * w * T / 2) / np.sinc(f * T))[:, None, None] if hold == "zoh" else H
    band = (f < 0.4 * fs)
    inpow = suu.max(axis=1)
    band &= inpow > 1e-3 * inpow[band].max() if band.any() else band
    K = np.zeros((ny, ny))
    D = np.zeros((ny, ny))
    B = np.zeros((ny, nu))
    sk = np.ones(nf)
    for it in range(iters):
        for i in range(ny):
            # unknowns: K_i(free), D_i(free), B_i(free)
            kj = np.flatnonzero(mask_K[i])
            dj = np.flatnonzero(mask_D[i])
            bm = np.flatnonzero(mask_B[i])
            rows_re, rows_im, rhs_re, rhs_im = [], [], [], []
            for m in range(nu):
                a = np.zeros((nf, len(kj) + len(dj) + len(bm)), complex)
                a[:, :len(kj)] = Hc[:, kj, m]
                a[:, len(kj):len(kj) + len(dj)] = 1j * w[:, None] * Hc[:, dj, m]
                for q, mm in enumerate(bm):
                    if mm == m:
                        a[:, len(kj) + len(dj) + q] = -1.0
                b = w ** 2 * Hc[:, i, m]
                wt = np.sqrt(coh[:, i]) * sk * band
                rows_re.append(a.real * wt[:, None])
                rows_im.append(a.imag * wt[:, None])
                rhs_re.append(b.real * wt)
                rhs_im.append(b.imag * wt)
            Am = np.vstack(rows_re + rows_im)
            bv = np.concatenate(rhs_re + rhs_im)
            colscale = np.maximum(np.linalg.norm(Am, axis=0), 1e-300)
            sol = np.linalg.lstsq(Am / colscale, bv, rcond=None)[0] / colscale
            K[i, kj] = sol[:len(kj)]
            D[i, dj] = sol[len(kj):len(kj) + len(dj)]
            B[i, bm] = sol[len(kj) + len(dj):]
        if it < iters - 1:
            det = np.array([abs(np.linalg.det(K + 1j * wk * D - wk ** 2 * np.eye(ny)))
                            for wk in w])
            sk = 1.0 / np.maximum(det, 1e-12 * max(det.max(), 1e-300)) ** (1.0 / ny)
            sk /= sk[band].max() if band.any() else 1.0
    K, D = stabilise(K, D)
    return K, D, B


def mechanical_initial(u, y, fs, mask_K, mask_D, mask_B, hold: str = "zoh"):
    """Initial mass-normalised (K, D, B) for a mechanical structure from data (n, nu), (n, ny)."""
    f, H, coh, suu = frf(u, y, fs)
    return levy_fit(f, H, coh, suu, fs, np.asarray(mask_K, bool), np.asarray(mask_D, bool),
                    np.asarray(mask_B, bool), hold=hold)
