"""What the final model still misses and no catalogue effect removed: is there any, where is
it, how much of the error it is, what it suggests.

:func:`report` is called on the validation part of the best model the forward selection
found. The residual counts as *structured* when the MATLAB-``resid``-style whiteness or
residual–input cross-correlation test fails, or its level is above the measurement-noise
estimate (:func:`noise_rms`). Then an entry is always returned (never a forced effect name),
followed by what narrows it down, each with its share of the error energy (0..1 of the
residual's energy on the validation part) and a suggestion:

* frequency bands (:func:`bands`): around each residual-spectrum peak above the noise floor,
  the band down to a tenth of the peak; the peak with the digits the spectral resolution
  supports (relative to the record's rate, never "0.1 Hz" for 0.0625 Hz at 1 Hz sampling);
* amplitude (:func:`amplitude`): an output that flattens at an edge of its range while the
  model goes on (saturation, overflow, end stop, clipping), or an error that grows faster
  than the amplitude of an output or input (or is largest at small amplitude);
* time (:func:`segments`): a stretch of the record holding most of the error;
* direction of input motion (:func:`direction`): error larger while an input rises than
  while it falls, or the reverse.

Levels are given in the record's units (the prefilter offsets added back), samples and
times from the record's start.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import signal

from rigd.diagnose import wording as W
from rigd.effects import numbers as N
from rigd.ident.thresholds import LEVEL_RATIO, MIN_FIT_GAIN, MIN_SHARE

#: most frequency bands reported
MAX_BANDS = 3
#: fit points (%) the structure must be worth to be reported: the effects' practical
#: significance
MIN_WORTH = MIN_FIT_GAIN


# --------------------------------------------------------------------------------------
# noise level and the "structured?" decision
# --------------------------------------------------------------------------------------
def noise_rms(x: np.ndarray, max_order: int = 4) -> float:
    """Upper estimate of the white measurement noise's rms in ``x`` (n,).

    The d-th difference of white noise of variance σ² has variance C(2d, d)·σ²; anything
    smooth adds to it, so each order gives an upper bound and the smallest is kept
    (differences of orders 1..``max_order``; the signal's own std as the last resort).
    """
    x = np.asarray(x, float)
    best = float(np.std(x))
    for d in range(1, max_order + 1):
        if x.shape[0] <= d + 2:
            break
        dx = np.diff(x, d)
        best = min(best, float(np.sqrt(np.mean(dx ** 2) / math.comb(2 * d, d))))
    return best


def level(r: np.ndarray, y: np.ndarray, ref: np.ndarray | None = None) -> dict[str, Any]:
    """Residual level against the noise estimate, all outputs pooled (r, y: (n, ny), each
    column in the same units).

    The noise estimate of each output is the smaller of the difference-based estimates
    (:func:`noise_rms`) of the output and of the residual and, when given, the rms of
    ``ref`` (n, ny): the residual of a reference model on the same samples (a black-box
    model, :mod:`rigd.ident.yardstick`). What a reference reaches is not noise: a
    difference-based estimate alone counts a fast response the model misses as noise.

    Returns ``{"rms", "noise_rms", "ratio", "structured_share"}``: ``structured_share`` is
    the share of the residual energy above the noise estimate (0..1).
    """
    r = np.atleast_2d(np.asarray(r, float).T).T
    y = np.atleast_2d(np.asarray(y, float).T).T
    ms = float(np.mean(np.sum((r - r.mean(axis=0)) ** 2, axis=1)))
    cap = [math.inf] * r.shape[1]
    if ref is not None:
        ref = np.atleast_2d(np.asarray(ref, float).T).T
        if ref.shape == r.shape and np.all(np.isfinite(ref)):
            cap = [float(np.std(ref[:, i])) for i in range(r.shape[1])]
    nv = float(sum(min(noise_rms(y[:, i]), noise_rms(r[:, i]), cap[i]) ** 2
                   for i in range(r.shape[1])))
    ratio = math.sqrt(ms / nv) if nv > 0 else math.inf
    share = min(max(1.0 - nv / ms, 0.0), 1.0) if ms > 0 else 0.0
    return {"rms": math.sqrt(ms), "noise_rms": math.sqrt(nv), "ratio": ratio,
            "structured_share": share}


def worth(lev: dict[str, Any], y: np.ndarray, r: np.ndarray) -> float:
    """Fit points (%) gained if the structured part of the residual were removed:
    (100 − fit)·(1 − sqrt(1 − structured share)), outputs pooled at unit std."""
    w = 1.0 / np.maximum(np.std(y, axis=0), 1e-300)
    err = 100.0 * float(np.mean(np.linalg.norm(r * w, axis=0)
                                / np.maximum(np.linalg.norm((y - y.mean(axis=0)) * w, axis=0),
                                             1e-300)))
    return err * (1.0 - math.sqrt(max(1.0 - lev["structured_share"], 0.0)))


# --------------------------------------------------------------------------------------
# where: frequency, amplitude, time, direction
# --------------------------------------------------------------------------------------
def digits_for(f: float, df: float) -> int:
    """Significant digits of a frequency ``f`` known to ± ``df`` (≥ 2)."""
    if f <= 0 or df <= 0:
        return 2
    return max(2, int(math.ceil(math.log10(f / df))) + 1)


def fmt(f: float, d: int) -> str:
    """``f`` with ``d`` significant digits (plain notation)."""
    return f"{float(f'{f:.{d}g}'):g}" if f != 0 else "0"


def bands(r: np.ndarray, fs: float, noise_var: float, max_bands: int = MAX_BANDS,
          min_share: float = MIN_SHARE) -> list[dict[str, Any]]:
    """Frequency bands holding the residual's structure.

    Welch PSD of ``r`` (n, ny) (outputs pooled; segments of n/4 up to 8192 samples); the
    white-noise floor is ``2·noise_var/fs``. Around the highest bin above the floor, the band
    extends while the PSD stays above a tenth of the peak (and above twice the floor); repeat
    on what is left. Returns ``[{"frequency_hz", "digits", "band_hz", "share"}]`` (share of
    the residual energy in the band), largest first; frequencies below Nyquist.
    """
    r = np.atleast_2d(np.asarray(r, float).T).T
    n = r.shape[0]
    if n < 16:
        return []
    nper = int(min(n, 2 ** int(np.log2(max(min(n // 4, 8192), 16)))))
    f, p = signal.welch(r, fs=fs, nperseg=nper, axis=0)
    p = p.sum(axis=1)
    tot = float(np.sum(p))
    if tot <= 0:
        return []
    df = float(f[1] - f[0])
    floor = 2.0 * noise_var / fs
    excess = np.maximum(p - floor, 0.0)
    used = np.zeros(p.shape, bool)
    out: list[dict[str, Any]] = []
    nyq = fs / 2.0
    for _ in range(4 * max_bands):
        cand = np.where(used, 0.0, excess)
        k = int(np.argmax(cand))
        if cand[k] <= 0 or len(out) >= max_bands:
            break
        thr = max(p[k] / 10.0, 2.0 * floor)
        lo, hi = k, k
        while lo > 0 and not used[lo - 1] and p[lo - 1] >= thr:
            lo -= 1
        while hi < len(p) - 1 and not used[hi + 1] and p[hi + 1] >= thr:
            hi += 1
        used[lo:hi + 1] = True
        share = float(np.sum(p[lo:hi + 1]) / tot)
        if share < min_share:
            continue
        fk = float(f[k])
        if 0 < k < len(p) - 1 and min(p[k - 1], p[k], p[k + 1]) > 0:  # parabolic on log p
            a, b, c = np.log(p[k - 1]), np.log(p[k]), np.log(p[k + 1])
            den = a - 2 * b + c
            if den < 0:
                fk += 0.5 * (a - c) / den * df
        fk = min(max(fk, 0.0), nyq * 0.999)
        edges = (max(0.0, float(f[lo]) - df / 2), min(nyq, float(f[hi]) + df / 2))
        d = max(digits_for(fk, df), digits_for(edges[1], df))
        out.append({"frequency_hz": float(fmt(fk, d)), "digits": d,
                    "band_hz": [float(fmt(edges[0], d)), float(fmt(edges[1], d))],
                    "share": share, "resolution_hz": df, "edges_raw": edges})
    return sorted(out, key=lambda b: -b["share"])


def _edge_pile(y: np.ndarray, yhat: np.ndarray, r: np.ndarray, edge: float = 0.03,
               min_pile: float = 0.10) -> dict[str, Any] | None:
    """An output that flattens at an edge of its range while the model goes beyond it.

    ``y``, ``yhat``, ``r`` (n,). The measured output piles up in the top (or bottom)
    ``edge`` of its range (≥ ``min_pile`` of the samples, where a smooth signal puts a few
    per cent) and the model's output passes that edge by more than the band's width, with
    the residual there of one sign (measurement short of the model).
    """
    lo, hi = float(np.min(y)), float(np.max(y))
    span = hi - lo
    if span <= 0:
        return None
    best = None
    for side in ("top", "bottom"):
        sgn = 1.0 if side == "top" else -1.0
        lim = hi if side == "top" else lo
        at_edge = sgn * (y - lim) >= -edge * span
        beyond = sgn * (yhat - lim) >= -edge * span
        pile = float(np.mean(at_edge))
        over = sgn * (float(np.max(yhat) if side == "top" else np.min(yhat)) - lim)
        if pile < min_pile or over < edge * span or not beyond.any():
            continue
        rb = r[beyond]
        if sgn * float(np.mean(rb)) > -0.5 * float(np.sqrt(np.mean(rb ** 2))):
            continue  # not short of the model on the whole there
        share = float(np.sum(rb ** 2) / max(np.sum(r ** 2), 1e-300))
        rng = [lim - edge * span, lim] if side == "top" else [lim, lim + edge * span]
        cand = {"side": side, "pile": pile, "limit": lim, "model_extreme": lim + sgn * over,
                "range": rng, "share": share, "n_beyond": int(beyond.sum())}
        if best is None or share > best["share"]:
            best = cand
    return best


def _by_quartile(r: np.ndarray, a: np.ndarray) -> dict[str, Any]:
    """Residual energy by quartile of |a − median a|: relative error in the top quartile
    (error rms / amplitude rms, against the whole record's) and in the bottom one."""
    dev = np.abs(a - np.median(a))
    q = np.quantile(dev, [0.25, 0.75])
    top, bot = dev >= q[1], dev <= q[0]
    ms = float(np.mean(r ** 2)) or 1e-300
    ma = float(np.mean(dev ** 2)) or 1e-300
    ms_top, ms_bot = float(np.mean(r[top] ** 2)), float(np.mean(r[bot] ** 2))
    grow = math.sqrt((ms_top / ms) / max(float(np.mean(dev[top] ** 2)) / ma, 1e-300))
    small = math.sqrt(ms_bot / ms)
    return {"top": [float(q[1]), float(np.max(dev))], "bottom": [0.0, float(q[0])],
            "grow": grow, "small": small,
            "share_top": float(np.sum(r[top] ** 2) / (ms * r.shape[0])),
            "share_bottom": float(np.sum(r[bot] ** 2) / (ms * r.shape[0])),
            "median": float(np.median(a))}


def amplitude(r: np.ndarray, y: np.ndarray, yhat: np.ndarray, u: np.ndarray,
              out_names: list[str], in_names: list[str],
              w: np.ndarray | None = None) -> list[dict[str, Any]]:
    """Where in amplitude the error lives (validation part; r, y, yhat (n, ny) in the
    outputs' units, u (n, nu); ``w`` (ny,) weights that pool the outputs, 1/std).

    An output flattening at an edge of its range while the model goes beyond (saturation)
    comes first; else the variable (model output or input) whose top quartile of
    |value − median| shows the relative error (error rms / amplitude rms, against the
    record's) growing ≥ 1.5× with ≥ 40 % of the error energy, or whose bottom quartile has
    ≥ 1.5× the average error rms with ≥ 40 % of it.
    """
    out: list[dict[str, Any]] = []
    w = np.ones(r.shape[1]) if w is None else np.asarray(w, float)
    rs = r * w
    tot = float(np.sum(rs ** 2)) or 1e-300
    for i, name in enumerate(out_names):
        pile = _edge_pile(y[:, i], yhat[:, i], r[:, i])
        if pile is not None:
            share = pile["share"] * float(np.sum(rs[:, i] ** 2)) / tot
            out.append({"kind": "saturation", "of": name, "side": pile["side"],
                        "range": pile["range"], "limit": pile["limit"],
                        "model_extreme": pile["model_extreme"], "pile": pile["pile"],
                        "share": share})
    if out:
        return sorted(out, key=lambda d: -d["share"])
    best = None
    pooled = np.sqrt(np.sum(rs ** 2, axis=1))
    cands = [(name, "output", yhat[:, i], rs[:, i]) for i, name in enumerate(out_names)]
    cands += [(name, "input", u[:, j], pooled) for j, name in enumerate(in_names)]
    for name, kind, a, rr in cands:
        if np.ptp(a) <= 0:
            continue
        q = _by_quartile(rr, a)
        part = float(np.sum(rr ** 2)) / tot
        for where, score, share in (("large", q["grow"], q["share_top"]),
                                    ("small", q["small"], q["share_bottom"])):
            if score >= 1.5 and share >= 0.4:
                cand = {"kind": f"{where} amplitude", "of": name, "variable": kind,
                        "range": q["top"] if where == "large" else q["bottom"],
                        "centre": q["median"], "ratio": score, "share": share * part}
                if best is None or cand["ratio"] > best["ratio"]:
                    best = cand
    return [best] if best is not None else []


def segments(r: np.ndarray, nseg: int = 10, z: float = 4.0) -> dict[str, Any] | None:
    """The stretch (consecutive tenths of the part) holding most of the error energy.

    Reported when one tenth holds ≥ 30 % of the energy *and* more than a stationary
    residual with the same autocorrelation would put there by chance: its mean energy
    exceeds the average by ≥ ``z`` standard deviations of a segment's mean energy
    (Gaussian process: relative std sqrt(2·Σ_k ρ_k² / n_seg), ρ the residual's
    autocorrelation; a narrow-band residual's energy fluctuates much more than white
    noise's). Returns ``{"samples": [a, b], "share"}`` (indices into ``r``) or None.
    """
    r = np.atleast_2d(np.asarray(r, float).T).T
    n = r.shape[0]
    if n < nseg * 4:
        return None
    parts = np.array_split(np.arange(n), nseg)
    e = np.array([float(np.sum(r[p] ** 2)) for p in parts])
    tot = float(e.sum()) or 1e-300
    s = e / tot
    k = int(np.argmax(s))
    if s[k] < 0.3:
        return None
    m = len(parts[k])
    rho2 = max(1.0 + 2.0 * float(np.sum(_acf(r[:, i], m - 1)[1:] ** 2))
               for i in range(r.shape[1]))
    rel_sd = math.sqrt(2.0 * rho2 / m)
    if s[k] * nseg - 1.0 < z * rel_sd:
        return None
    lo, hi = k, k
    while lo > 0 and s[lo - 1] >= 2.0 / nseg:
        lo -= 1
    while hi < nseg - 1 and s[hi + 1] >= 2.0 / nseg:
        hi += 1
    return {"samples": [int(parts[lo][0]), int(parts[hi][-1]) + 1],
            "share": float(np.sum(s[lo:hi + 1]))}


def _acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    x = x - x.mean()
    nfft = 1 << int(np.ceil(np.log2(2 * x.shape[0])))
    f = np.fft.rfft(x, nfft)
    ac = np.fft.irfft(f * np.conj(f), nfft)[:max_lag + 1]
    return ac / ac[0] if ac[0] > 0 else np.zeros(max_lag + 1)


def direction(r: np.ndarray, u: np.ndarray, in_names: list[str]) -> dict[str, Any] | None:
    """Error energy per sample while an input rises against while it falls: the input with
    the largest ratio when ≥ 2× (both directions ≥ 10 % of the samples)."""
    r = np.atleast_2d(np.asarray(r, float).T).T
    e = np.sum(r ** 2, axis=1)
    tot = float(e.sum()) or 1e-300
    best = None
    for j, name in enumerate(in_names):
        du = np.gradient(u[:, j])
        tol = 1e-9 * (float(np.ptp(u[:, j])) or 1.0)
        up, dn = du > tol, du < -tol
        n = e.shape[0]
        if up.sum() < 0.1 * n or dn.sum() < 0.1 * n:
            continue
        mu, md = float(np.mean(e[up])), float(np.mean(e[dn]))
        if min(mu, md) <= 0:
            continue
        ratio = max(mu, md) / min(mu, md)
        worse = "rises" if mu > md else "falls"
        if ratio >= 2.0 and (best is None or ratio > best["ratio"]):
            m = up if mu > md else dn
            best = {"input": name, "worse": worse, "ratio": ratio,
                    "share": float(np.sum(e[m]) / tot)}
    return best


# --------------------------------------------------------------------------------------
# the report
# --------------------------------------------------------------------------------------
def _band_suggestion(b: dict[str, Any], resonances: list[float], nyq: float,
                     domain: str = "generic") -> str:
    lo, hi = b["edges_raw"]
    f = b["frequency_hz"]
    near = [fr for fr in resonances if lo - 0.1 * fr <= fr <= hi + 0.1 * fr]
    if lo <= 0.0 and hi < 0.1 * nyq:
        return ("slow structure: a drift or a slow process outside the model's dynamics "
                "(level- or temperature-dependent behaviour, a slow mode); a longer record "
                "with slower excitation would show it")
    if near:
        return W.band_near_model(near, domain)
    if hi - lo <= 0.3 * max(f, 1e-300):
        return W.band_narrow(domain)
    return ("broad-band dynamics the model lacks in this band (a lag, a mode or a "
            "nonlinearity); excite the band alone to narrow it down")


def report(r: np.ndarray, y: np.ndarray, yhat: np.ndarray, u: np.ndarray, fs: float,
           tests: dict[str, Any], resonances: list[float], out_names: list[str],
           in_names: list[str], skip_hz: list[float] | None = None,
           offsets: dict[str, float] | None = None, start: int = 0,
           reference: dict[str, Any] | None = None,
           domain: str = "generic") -> list[dict[str, Any]]:
    """Unexplained structure of a residual ``r`` = ``y`` − ``yhat`` (validation part).

    Parameters
    ----------
    r, y, yhat : ndarray (n, ny)
        Residual, measured and simulated outputs (prefiltered: offsets removed). Outputs
        are pooled after scaling each to unit std of ``y``.
    u : ndarray (n, nu)
        Inputs.
    fs : float
        Sampling rate (Hz).
    tests : dict
        ``{"whiteness": {name: {"passed", "outside"}}, "cross_correlation": {...}}``.
    resonances : list of float
        The model's resonance frequencies (Hz).
    skip_hz : list of float, optional
        Frequencies already explained elsewhere (run-out harmonics): bands holding them
        are not reported.
    offsets : dict, optional
        Prefilter offsets per channel, added back so levels are in the record's units.
    start : int
        Index of the first sample of ``r`` in the record (times and samples reported).
    reference : dict, optional
        What is reachable: ``{"residual": (n, ny), "fit": %, "model_fit": %, "label": str}``
        of the best black-box reference on the same split (:mod:`rigd.ident.yardstick`).
        Its residual caps the noise estimate, and a model ≥ ``MIN_WORTH`` points below it
        always has structure left (a 9 % fit is never "nothing unexplained").
    domain : str
        The record's domain (:mod:`rigd.diagnose.domain`): the words of the suggestions.

    Returns
    -------
    list of dict
        Empty when the residual is not structured; else first the summary entry
        (``where: {"residual": "structured", ...}``, ``share`` = share of the error energy
        above the noise estimate), then bands (``where.frequency_hz``, ``band_hz``),
        amplitude (``where.amplitude_range``, ``of``), time (``where.samples``) and
        direction (``where.direction``) entries, each with ``share``, ``text`` and
        ``suggests``.
    """
    r, y, yhat, u = (np.atleast_2d(np.asarray(x, float).T).T for x in (r, y, yhat, u))
    offsets = offsets or {}
    w = 1.0 / np.maximum(np.std(y, axis=0), 1e-300)
    ref_r = reference.get("residual") if reference else None
    lev = level(r * w, y * w, None if ref_r is None else np.asarray(ref_r, float) * w)
    gap = (float(reference["fit"]) - float(reference["model_fit"])) if reference else 0.0
    why = _why(tests, lev, reference if gap >= MIN_WORTH else None)
    if not why or (worth(lev, y, r) < MIN_WORTH and gap < MIN_WORTH):
        return []
    found = _band_entries(r * w, fs, lev, resonances, skip_hz, domain)
    found += _amplitude_entries(r, y, yhat, u, out_names, in_names, w, offsets)
    found += _segment_entry(r * w, fs, start)
    found += _direction_entry(r * w, u, in_names)
    return [_head(lev, why, found)] + found


def _why(tests: dict[str, Any], lev: dict[str, Any],
         reference: dict[str, Any] | None) -> list[str]:
    """Why the residual counts as structured (empty: it does not)."""
    white = [(k, v["outside"]) for k, v in tests.get("whiteness", {}).items()
             if not v["passed"]]
    cross = [(k, v["outside"]) for k, v in tests.get("cross_correlation", {}).items()
             if not v["passed"]]
    why = []
    if reference is not None:
        why.append(f"{reference['label']} reaches {reference['fit']:.2f} % on the same split "
                   f"against this model's {reference['model_fit']:.2f} %")
    if white:
        why.append("whiteness fails (" + ", ".join(f"{k}: {N.share(o)} of lags outside the "
                                                   "99 % bound" for k, o in white) + ")")
    if cross:
        why.append("the residual correlates with the input (" + ", ".join(
            f"{k}: {N.share(o)} of lags" for k, o in cross) + ")")
    if lev["ratio"] > LEVEL_RATIO:
        why.append(f"its rms is {lev['ratio']:.1f}× the measurement-noise estimate")
    return why


def _band_entries(rw: np.ndarray, fs: float, lev: dict[str, Any], resonances: list[float],
                  skip_hz: list[float] | None, domain: str) -> list[dict[str, Any]]:
    """Frequency bands holding the structure (:func:`bands`), run-out harmonics skipped."""
    found = []
    for b in bands(rw, fs, lev["noise_rms"] ** 2):
        lo, hi = b["band_hz"]
        if skip_hz and any(lo - 0.03 * h <= h <= hi + 0.03 * h for h in skip_hz):
            continue
        d = b["digits"]
        sugg = _band_suggestion(b, resonances, fs / 2.0, domain)
        found.append({
            "where": {"frequency_hz": b["frequency_hz"], "band_hz": b["band_hz"]},
            "share": round(b["share"], 4),
            "suggests": sugg,
            "text": (f"{N.share(b['share'])} of the error energy lies in "
                     f"{fmt(lo, d)}–{fmt(hi, d)} Hz (peak {N.freq(b['frequency_hz'], fs)}"
                     f"; spectral resolution "
                     f"{fmt(b['resolution_hz'], 2)} Hz): {sugg}")})
    return found


def _amplitude_entries(r, y, yhat, u, out_names, in_names, w,
                       offsets: dict[str, float]) -> list[dict[str, Any]]:
    """Where in amplitude the error lives (:func:`amplitude`), in the record's units."""
    found = []
    for a in amplitude(r, y, yhat, u, out_names, in_names, w):
        off = float(offsets.get(a["of"], 0.0))
        if a["kind"] == "saturation":
            found.append(_saturation_entry(a, off))
            continue
        big = a["kind"] == "large amplitude"
        sugg = ("an amplitude-dependent effect outside the catalogue (saturation, "
                "softening, a limit)" if big else
                "an effect at small amplitude (dead zone, friction, backlash, "
                "quantisation)") + "; repeat the experiment at another amplitude"
        lo, hi = a["range"]
        a["centre"] += off
        text = (f"{N.share(a['share'])} of the error energy lies at "
                f"{'large' if big else 'small'} {a['variable']} amplitude "
                f"(|{a['of']} − {a['centre']:.4g}| in {lo:.4g}..{hi:.4g}, a quarter of the "
                f"samples), where the error is {a['ratio']:.1f}× "
                f"{'what the amplitude alone gives' if big else 'its average'}: {sugg}")
        where = {"amplitude_range": [float(f"{lo:.6g}"), float(f"{hi:.6g}")],
                 "of": a["of"], "variable": a["variable"], "about": a["centre"],
                 "amplitude": "large" if big else "small"}
        found.append({"where": where, "share": round(a["share"], 4), "suggests": sugg,
                      "text": text})
    return found


def _saturation_entry(a: dict[str, Any], off: float) -> dict[str, Any]:
    a["limit"] += off
    a["model_extreme"] += off
    a["range"] = [v + off for v in a["range"]]
    sugg = ("a saturation outside the catalogue (overflow, end stop, clipping, a "
            "limited actuator); repeat at amplitudes that stay below the limit, or "
            "model the limit")
    ext = "maximum" if a["side"] == "top" else "minimum"
    text = (f"{N.share(a['share'])} of the error energy lies where the model's "
            f"{a['of']} goes past the measured {ext}: "
            f"the measured {a['of']} flattens at {a['limit']:.4g} ({N.share(a['pile'])} "
            f"of the samples within the {a['side']} 3 % of its range) while the model "
            f"reaches {a['model_extreme']:.4g}: {sugg}")
    where = {"amplitude_range": [float(f"{v:.6g}") for v in a["range"]],
             "of": a["of"], "variable": "output", "saturation": a["side"]}
    return {"where": where, "share": round(a["share"], 4), "suggests": sugg, "text": text}


def _segment_entry(rw: np.ndarray, fs: float, start: int) -> list[dict[str, Any]]:
    seg = segments(rw)
    if seg is None:
        return []
    a, b = (v + start for v in seg["samples"])
    sugg = ("something changed during the record (a disturbance, a drift, another "
            "operating state); look at that stretch and repeat the experiment")
    return [{"where": {"samples": [a, b],
                       "time_s": [float(f"{a / fs:.6g}"), float(f"{b / fs:.6g}")]},
             "share": round(seg["share"], 4), "suggests": sugg,
             "text": (f"{N.share(seg['share'])} of the error energy lies in "
                      f"samples {a}..{b} (t = {a / fs:.4g}..{b / fs:.4g} s of the "
                      f"record): {sugg}")}]


def _direction_entry(rw: np.ndarray, u: np.ndarray, in_names: list[str]
                     ) -> list[dict[str, Any]]:
    dr = direction(rw, u, in_names)
    if dr is None:
        return []
    sugg = ("direction-dependent physics outside the catalogue (friction, hysteresis "
            "in another place, different filling and emptying paths); a slow triangle "
            "input would show it")
    return [{"where": {"direction": f"{dr['input']} {dr['worse']}"},
             "share": round(dr["share"], 4), "suggests": sugg,
             "text": (f"the error is {dr['ratio']:.1f}× larger while {dr['input']} "
                      f"{dr['worse']} than the other way ({N.share(dr['share'])} of "
                      f"the error energy): {sugg}")}]


def _head(lev: dict[str, Any], why: list[str], found: list[dict[str, Any]]
          ) -> dict[str, Any]:
    """The summary entry: why the residual is structured and where it lives."""
    total = lev["structured_share"]
    places = "; ".join(f["text"].split(":")[0] for f in found) or (
        "spread over frequency, amplitude, time and direction: no narrower place found")
    return {"where": {"residual": "structured",
                      "rms_over_noise": round(min(lev["ratio"], 1e6), 3)},
            "share": round(total, 4),
            "suggests": ("a physical effect outside the catalogue" if found else
                         "a longer record or another excitation to narrow it down"),
            "text": (f"the final model's residual is structured ({'; '.join(why)}): about "
                     f"{N.share(total)} of the error energy is above the noise estimate and "
                     f"no catalogue effect removed it. Where: {places}")}
