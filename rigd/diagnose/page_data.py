"""Data of the interactive model pages: one record's measured output and a model's views.

Plain functions returning JSON-ready dicts (numpy arrays inside; :func:`rigd.htmlpage.json_safe`
makes them JSON) that ``rigd/page_assets/report.js`` draws:

* :func:`measured_view` — the measured outputs (min/max decimated time traces) and their
  spectrum;
* :func:`model_view` — one model's simulated outputs and residual ε = y − ŷ (decimated), fit
  per output (%), residual RMS, residual spectrum (Welch), residual RMS by amplitude of the
  measured output, mean residual by shaft angle (when the record has φ);
* :func:`resonances_below_nyquist` — the model's resonances the spectrum can show.

The compare page (:mod:`rigd.diagnose.compare_page`) has one model view per sub-model; the
diagnose page (:mod:`rigd.diagnose.diagnose_page`) one per model ``diagnose`` fitted (base,
each forward-selection step, the final model with each remaining effect).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

from rigd.diagnose import residual as R
from rigd.htmlpage import minmax_decimate
from rigd.ident.figures import fit_percent

#: most points of one time trace on the page (min/max decimation beyond)
TRACE_POINTS = 2000
#: most Welch segment length (frequency lines = half of it)
SPECTRUM_NPERSEG = 1024
#: shaft-angle bins of the polar plot and amplitude bins
ANGLE_BINS = 36
AMPLITUDE_BINS = 8


def resonances_below_nyquist(resonances_hz, fs: float) -> list[float]:
    """The resonances (Hz) strictly between 0 and the Nyquist frequency fs/2, sorted.

    A continuous-time model can have modes above fs/2 (fitted to nothing the record shows);
    the residual spectrum ends at fs/2, so they are not marked on it.
    """
    return sorted(float(f) for f in resonances_hz if 0.0 < float(f) < 0.5 * fs)


def _traces(t: np.ndarray, y: np.ndarray, points: int) -> list[dict[str, np.ndarray]]:
    out = []
    for i in range(y.shape[1]):
        x, v = minmax_decimate(t, y[:, i], points)
        out.append({"x": x, "y": v})
    return out


def _spectrum(r: np.ndarray, fs: float) -> dict[str, np.ndarray]:
    """Welch PSD summed over the columns of ``r`` (n, k): {"f" Hz, "p" units²/Hz}."""
    n = r.shape[0]
    nper = int(min(n, SPECTRUM_NPERSEG, 2 ** int(np.log2(max(n // 8, 64)))))
    f, p = signal.welch(r - r.mean(axis=0), fs=fs, nperseg=nper, axis=0)
    return {"f": f, "p": np.atleast_2d(p.T).T.sum(axis=1)}


def measured_view(t: np.ndarray, y: np.ndarray, fs: float, sl: slice,
                  points: int = TRACE_POINTS) -> dict[str, Any]:
    """The measured outputs: decimated traces of the whole record, spectrum over ``sl``.

    Parameters
    ----------
    t : ndarray (n,)
        Time, s.
    y : ndarray (n, ny)
        Measured outputs (units of the record).
    fs : float
        Sample rate, Hz.
    sl : slice
        Samples the statistics are taken on (validation part, or all).
    """
    return {"traces": _traces(t, y, points), "spectrum": _spectrum(y[sl], fs)}


def model_view(t: np.ndarray, y: np.ndarray, yhat: np.ndarray, fs: float, sl: slice,
               phi: np.ndarray | None = None, points: int = TRACE_POINTS) -> dict[str, Any]:
    """One model's simulated output and where its residual lies, on samples ``sl``.

    Parameters
    ----------
    t, y, fs, sl
        As :func:`measured_view`.
    yhat : ndarray (n, ny)
        The model's simulated outputs over the whole record.
    phi : ndarray (n,), optional
        Shaft angle, rad (the polar view is made only with it).

    Returns
    -------
    dict
        ``fit_percent`` (mean over outputs, %), ``fit_per_output``, ``error_percent``
        (100 − fit), ``residual_rms`` per output, decimated ``traces`` (ŷ) and ``residual``
        (ε) of the whole record, ``spectrum`` of ε over ``sl``, ``amplitude`` (bin centres of
        |y − ȳ|, max over outputs, and ε RMS per bin), ``angle`` (bin centres in degrees and
        mean ε per output) or None.
    """
    r = y - yhat
    fp = fit_percent(y[sl], yhat[sl])
    a = np.abs(y[sl] - y[sl].mean(axis=0)).max(axis=1)
    edges, rms = R.by_amplitude(r[sl], a, AMPLITUDE_BINS)
    view: dict[str, Any] = {
        "fit_percent": float(np.mean(fp)),
        "fit_per_output": fp,
        "error_percent": 100.0 - float(np.mean(fp)),
        "residual_rms": np.sqrt(np.mean(r[sl] ** 2, axis=0)),
        "traces": _traces(t, yhat, points),
        "residual": _traces(t, r, points),
        "spectrum": _spectrum(r[sl], fs),
        "amplitude": {"centre": 0.5 * (edges[1:] + edges[:-1]), "rms": rms},
        "angle": None,
    }
    if phi is not None and len(phi) == len(y):
        cen, mean = R.by_angle(r[sl], phi[sl], ANGLE_BINS)
        view["angle"] = {"deg": np.degrees(cen), "mean": mean.T}
    return view
