"""``extra_mode``: an unmodelled structural mode.

Signature: a narrow peak in the residual, coherent with the input, at a frequency the model
lacks (away from the model's resonances). The peak is found in the residual–input cross
spectrum; its half-power width gives the damping. The regressors are the mode's responses
(displacement and velocity) to each input, on each output. Extension: a parallel mode
ω²/(s² + 2ζω s + ω²) from every input to every output with fitted frequency, damping and
gains (additive output term).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from rigd.effects._linear import parallel
from rigd.effects.base import Effect, dims
from rigd.effects.context import Context
from rigd.effects.scales import pow2_ceil, pow2_floor
from rigd.effects.signature import SignatureFit, signature_fit
from rigd.lti import resonator

MIN_SEPARATION = 0.15   # relative distance from a model resonance
PEAK_RATIO = 4.0        # peak over the local median of the explained power
#: spectral resolution, relative to the model's lowest resonance: 1/32 of it, so the
#: exclusion band (± MIN_SEPARATION) around it spans ≥ 4 bins
RESOLUTION = 1.0 / 32
#: at least this many (half-overlapping) Welch segments of the estimation part
MIN_SEGMENTS = 3
#: frequency bounds of the mode, relative: above two periods of the estimation part, below
#: this share of the Nyquist frequency (as rigd.ident.greybox.order)
F_MAX_NYQUIST = 0.95


def segment_length(n: int, fs: float, resonances_hz=()) -> int:
    """Welch segment (samples) of the residual search, relative to the record: fine enough
    to resolve the model's lowest resonance to ``RESOLUTION`` of itself, coarse enough for
    ``MIN_SEGMENTS`` segments in ``n`` samples (≥ 256, ≤ n). Without resonances: n/8.
    Depends on the rate only through fs/f, so the same samples at another rate give the
    same segments."""
    low = [f for f in resonances_hz if f > 0]
    want = pow2_ceil(fs / (RESOLUTION * min(low))) if low else pow2_floor(n / 8)
    return int(min(n, max(256, min(want, pow2_floor(n / MIN_SEGMENTS)))))


def explained_power(u: np.ndarray, r: np.ndarray, fs: float, nperseg: int):
    """Frequency grid and the residual power explained linearly by the inputs,
    Σ_ij |S_{u_j r_i}|² / S_{u_j u_j}, with the coherence of the best pair."""
    n = u.shape[0]
    nperseg = int(min(nperseg, n))
    f = None
    E = 0.0
    coh = 0.0
    for j in range(u.shape[1]):
        f, suu = signal.welch(u[:, j], fs=fs, nperseg=nperseg)
        for i in range(r.shape[1]):
            _, sur = signal.csd(u[:, j], r[:, i], fs=fs, nperseg=nperseg)
            _, srr = signal.welch(r[:, i], fs=fs, nperseg=nperseg)
            e = np.abs(sur) ** 2 / np.maximum(suu, 1e-300)
            E = E + e
            coh = np.maximum(coh, e / np.maximum(srr, 1e-300))
    return f, E, coh


def find_peak(f, E, coh, exclude_hz, fmin_hz: float):
    """(f_peak, zeta) of the strongest narrow coherent peak away from ``exclude_hz``."""
    ok = f >= fmin_hz
    for fr in exclude_hz:
        ok &= np.abs(f - fr) > MIN_SEPARATION * fr
    if not np.any(ok):
        return None
    cand = np.where(ok, E, 0.0)
    order = np.argsort(cand)[::-1]
    for k in order[:5]:
        if cand[k] <= 0 or coh[k] < 0.3:
            continue
        lo, hi = max(0, int(k * 0.7)), min(len(f), int(k * 1.3) + 2)
        med = np.median(E[lo:hi])
        if E[k] < PEAK_RATIO * max(med, 1e-300):
            continue
        half = E[k] / 2
        a = k
        while a > 0 and E[a] > half:
            a -= 1
        b = k
        while b < len(E) - 1 and E[b] > half:
            b += 1
        bw = max(f[b] - f[a], f[1] - f[0])
        zeta = float(np.clip(bw / (2 * f[k]), 0.003, 0.2))
        return float(f[k]), zeta
    return None


class ExtraMode(Effect):
    name = "extra_mode"
    sites = ("output",)
    #: its output block is y + g(u, θ): the base's output sensitivities hold through it
    additive_output = True
    submodels = ("bearing", "generic")
    physics = "an unmodelled structural mode"

    def _search(self, ctx: Context):
        n_est = len(range(*ctx.est.indices(ctx.n)))
        nper = segment_length(n_est, ctx.fs, ctx.resonances_hz)
        f, E, coh = explained_power(ctx.u[ctx.est], ctx.residual[ctx.est], ctx.fs, nper)
        ex = list(ctx.resonances_hz)
        if ctx.omega_hz > 0:
            ex += [ctx.omega_hz, 2 * ctx.omega_hz]
        return find_peak(f, E, coh, ex, fmin_hz=3 * ctx.fs / nper)

    def signature(self, ctx):
        pk = self._search(ctx)
        if pk is None:
            sig = SignatureFit(0.0, np.zeros(0), 1.0, 0)
            sig.extra["peak"] = None
            return sig
        sig = signature_fit(ctx, self._regs(ctx, *pk))
        sig.extra["peak"] = pk
        return sig

    def _regs(self, ctx, f0, zeta):
        regs = []
        for j in range(ctx.nu):
            d, v = resonator(ctx.u[:, j], f0, zeta, ctx.fs)
            for s in (d, v):
                for i in range(ctx.ny):
                    g = np.zeros((ctx.n, ctx.ny))
                    g[:, i] = s
                    regs.append(g)
        return regs

    def regressors(self, ctx):
        pk = self._search(ctx)
        return [] if pk is None else self._regs(ctx, *pk)

    def evidence(self, ctx, sig):
        """Evidence code (``peak`` / ``no_peak``) and numbers (rigd.diagnose.wording)."""
        pk = sig.extra.get("peak")
        if pk is None:
            return "no_peak", {}
        f0, zeta = pk
        return "peak", {"frequency_hz": f0, "zeta": zeta,
                        "model_peaks_hz": list(ctx.resonances_hz)}

    # --- extension -------------------------------------------------------------------
    def param_names(self, base):
        ny, nu = dims(base)
        return (["mode_f_hz", "mode_zeta"]
                + [f"mode_g{j}_{i}" for j in range(nu) for i in range(ny)]
                + [f"mode_h{j}_{i}" for j in range(nu) for i in range(ny)])

    def param_bounds(self, base):
        k = len(self.param_names(base))
        lo, hi = np.full(k, -np.inf), np.full(k, np.inf)
        lo[0] = 0.0
        lo[1], hi[1] = 1e-4, 0.7
        return lo, hi

    def record_bounds(self, base, rec):
        lo, hi = self.param_bounds(base)
        lo[0], hi[0] = rec.lowest_hz, F_MAX_NYQUIST * rec.nyquist_hz
        return lo, hi

    def theta0_effect(self, base, data):
        """Start at the strongest coherent output peak away from the base's resonances."""
        ny, nu = dims(base)
        u, y, fs = np.asarray(data.inputs, float), np.asarray(data.outputs, float), float(data.fs)
        nper = segment_length(len(u), fs)
        f, E, coh = explained_power(u - u.mean(0), y - y.mean(0), fs, nper)
        k = int(np.argmax(E))
        pk = find_peak(f, E, coh, [f[k]], 3 * fs / nper) or (float(f[k]) * 1.5, 0.02)
        return np.concatenate([[pk[0], pk[1]], np.zeros(2 * ny * nu)])

    def warm_start(self, ctx, sig):
        pk = sig.extra.get("peak")
        if pk is None:
            return None
        b = np.asarray(sig.beta, float).reshape(ctx.nu, 2, ctx.ny)
        return np.concatenate([[pk[0], pk[1]], b[:, 0, :].ravel(), b[:, 1, :].ravel()])

    def linear(self, G, theta_e, base, fs):
        """The parallel mode: per input j, q̈ + 2ζω q̇ + ω² q = ω² u_j, y += g_j q + h_j q̇/ω
        (the continuous system ``output_block`` discretises)."""
        nu, ny = G.ninputs, G.noutputs
        th = np.asarray(theta_e, float)
        w, zeta = 2 * np.pi * th[0], th[1]
        g = th[2:2 + nu * ny].reshape(nu, ny)
        h = th[2 + nu * ny:].reshape(nu, ny)
        A, B, C = np.zeros((2 * nu, 2 * nu)), np.zeros((2 * nu, nu)), np.zeros((ny, 2 * nu))
        for j in range(nu):
            A[2 * j:2 * j + 2, 2 * j:2 * j + 2] = [[0.0, 1.0], [-w * w, -2 * zeta * w]]
            B[2 * j + 1, j] = w * w
            C[:, 2 * j] = g[j]
            C[:, 2 * j + 1] = h[j] / w
        return parallel(G, A, B, C)

    def output_block(self, y, theta_e, data):
        """y + Σ_j (g_j q_j + h_j q̇_j/ω): the parallel mode driven by each input."""
        u = np.asarray(data.inputs, float)
        ny, nu = y.shape[1], u.shape[1]
        th = np.asarray(theta_e, float)
        f0, zeta = th[0], th[1]
        g = th[2:2 + nu * ny].reshape(nu, ny)
        h = th[2 + nu * ny:].reshape(nu, ny)
        if not (np.any(g) or np.any(h)):
            return y
        out = y.copy()
        for j in range(nu):
            d, v = resonator(u[:, j], f0, zeta, float(data.fs))
            out += d[:, None] * g[j][None, :] + v[:, None] * h[j][None, :]
        return out
