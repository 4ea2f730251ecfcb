"""Damping ratio and frequency of an impact response (paper Sec. 6, Figs. 6–7).

After the impact force has died away the shaft displacement of one axis is fitted by a
damped sinusoid (one mode, the free response)::

    y(t) = A·exp(−ζ ω_n t)·cos(ω_d t + φ) + c,     ω_d = ω_n·sqrt(1 − ζ²)

by nonlinear least squares (scipy ``least_squares``) from a starting point found by the
FFT peak and the Hilbert-envelope decay. The uncertainty (one standard deviation) of ω_n and
ζ comes from the Jacobian at the optimum scaled by the residual variance (Gauss–Newton
covariance; the residual of a simulated or measured record is treated as white).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import hilbert

from rigd.errors import InputError
from rigd.ident.figures import fit_percent


@dataclass
class ImpactFit:
    """Result of :func:`fit_damped_sinusoid` (frequencies in Hz, t in s)."""

    f_hz: float
    zeta: float
    f_std: float
    zeta_std: float
    amplitude: float
    t0: float
    window_s: float
    fit_percent: float

    def to_dict(self) -> dict:
        return {k: float(v) for k, v in asdict(self).items()}


def _model(th, t):
    A, zeta, wn, phi, c = th
    wd = wn * np.sqrt(max(1.0 - zeta * zeta, 1e-9))
    return A * np.exp(-zeta * wn * t) * np.cos(wd * t + phi) + c


def fit_damped_sinusoid(t: np.ndarray, y: np.ndarray, *, f_range_hz=(20.0, 1000.0)
                        ) -> ImpactFit:
    """Fit one damped sinusoid to a free response ``y(t)`` (t from the start of the window).

    Parameters
    ----------
    t, y : ndarray
        Time (s) and response (any unit), uniformly sampled, starting after the force.
    f_range_hz : (float, float)
        Where to look for the FFT peak used as the starting frequency.

    Raises
    ------
    InputError
        Too short a window or a response without any oscillation.
    """
    t = np.asarray(t, float) - float(t[0])
    y = np.asarray(y, float)
    if len(y) < 16:
        raise InputError(f"impact window too short ({len(y)} samples)", "impact")
    dt = float(np.median(np.diff(t)))
    y0 = y - np.mean(y[-max(4, len(y) // 5):])
    if not np.any(np.abs(y0) > 0):
        raise InputError("impact response is flat: no oscillation to fit", "impact")
    nfft = 1 << int(np.ceil(np.log2(len(y0) * 8)))
    spec = np.abs(np.fft.rfft(y0, nfft))   # no taper: the response is at the start
    freqs = np.fft.rfftfreq(nfft, dt)
    sel = (freqs >= f_range_hz[0]) & (freqs <= f_range_hz[1])
    if not sel.any():
        raise InputError("impact window too short for the frequency range", "impact")
    f0 = float(freqs[sel][np.argmax(spec[sel])])
    env = np.abs(hilbert(y0))
    i0 = int(np.argmax(env))
    below = np.nonzero(env[i0:] < 0.1 * env[i0])[0]
    i1 = i0 + (int(below[0]) if below.size else len(env) - i0)
    if i1 - i0 > 3:
        slope = np.polyfit(t[i0:i1], np.log(np.maximum(env[i0:i1], 1e-300)), 1)[0]
    else:
        slope = -0.05 * 2 * np.pi * f0
    w0 = 2 * np.pi * f0
    z0 = float(np.clip(-slope / w0, 0.005, 0.8))
    A0 = float(env.max())
    # fit where the response stands above the noise: 3x the 10 % decay time, >= 6 periods
    end = int(min(len(y), max(3 * i1, i0 + 6.0 / (f0 * dt), 16)))
    t, y = t[:end], y[:end]
    best = None
    for phi0 in (0.0, np.pi / 2, np.pi, -np.pi / 2):
        r = least_squares(lambda th: _model(th, t) - y, [A0, z0, w0, phi0, float(np.mean(y))],
                          bounds=([-np.inf, 1e-4, 0.5 * w0, -np.inf, -np.inf],
                                  [np.inf, 0.99, 2.0 * w0, np.inf, np.inf]),
                          x_scale=[A0, 0.05, w0 * 0.05, 1.0, A0], method="trf")
        if best is None or r.cost < best.cost:
            best = r
    th = best.x
    res = best.fun
    dof = max(1, len(y) - len(th))
    s2 = float(res @ res) / dof
    try:
        J = best.jac
        cov = np.linalg.pinv(J.T @ J) * s2
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        std = np.full(len(th), np.nan)
    A, zeta, wn, phi, c = th
    if A < 0:
        A = -A
    fit = float(fit_percent(y, y + res)[0])  # res = model − y
    return ImpactFit(f_hz=float(wn / (2 * np.pi)), zeta=float(zeta),
                     f_std=float(std[2] / (2 * np.pi)), zeta_std=float(std[1]),
                     amplitude=float(A), t0=0.0, window_s=float(t[-1]), fit_percent=float(fit))


def impact_window(f: np.ndarray, fs: float, *, threshold: float = 0.05,
                  settle_s: float = 0.0005) -> tuple[int, int]:
    """(start of impact, first sample after the force) from a force signal ``f`` (N)."""
    f = np.abs(np.asarray(f, float))
    if not np.any(f > 0):
        raise InputError("no impact force in the record (force channel is zero)", "impact")
    peak = f.max()
    on = np.nonzero(f > threshold * peak)[0]
    start, end = int(on[0]), int(on[-1]) + 1
    return start, min(len(f), end + int(round(settle_s * fs)))


def analyze_axis(t: np.ndarray, e: np.ndarray, force: np.ndarray, fs: float, *,
                 window_s: float = 0.08, axis: str = "x") -> dict:
    """Fit the free response of displacement ``e`` after the impact in ``force``."""
    start, after = impact_window(force, fs)
    stop = min(len(e), after + int(round(window_s * fs)))
    if stop - after < 16:
        raise InputError(f"axis {axis}: record ends {stop - after} samples after the impact; "
                         "need a longer post-impact recording", "impact")
    fit = fit_damped_sinusoid(t[after:stop], e[after:stop])
    d = fit.to_dict()
    d.update({"axis": axis, "t_impact_s": float(t[start]), "t_fit_start_s": float(t[after]),
              "force_peak_n": float(np.max(np.abs(force)))})
    return d


def analyze_record(record, *, window_s: float = 0.08, axes=None) -> dict:
    """Impact analysis of a :class:`rigd.data.record.Record` with ``f_x``/``f_y`` channels.

    Each axis whose force channel holds an impact is fitted on its own displacement
    (``e_x`` for ``f_x``...). Returns ``{"axes": {"x": {...}, ...}, "omega_rpm", "p_inj_bar"}``.
    """
    cols = record.columns
    for name in ("e_x", "e_y"):
        if name not in cols:
            raise InputError(f"record has no {name} channel", record.source)
    n = len(record)
    t = cols["t"] if "t" in cols else np.arange(n) / record.fs
    out = {}
    for ax in (axes or ("x", "y")):
        fcol = f"f_{ax}"
        if fcol not in cols or not np.any(np.abs(cols[fcol]) > 0):
            continue
        out[ax] = analyze_axis(t, cols[f"e_{ax}"], cols[fcol], record.fs, window_s=window_s,
                               axis=ax)
    if not out:
        raise InputError("record has no impact: f_x and f_y are zero or missing", record.source)
    meta = record.meta or {}
    return {"axes": out, "omega_rpm": meta.get("omega_rpm"), "p_inj_bar": meta.get("p_inj_bar"),
            "controller_on": meta.get("controller_on", meta.get("controller"))}
