"""Tustin discretisation of K∞(s) to K∞(z) at the loop rate (paper Sec. 5, Fig. 5)."""

from __future__ import annotations


def tustin(K, fs_hz: float, prewarp_hz: float | None = None):
    """K∞(z) = K∞(s) with s = 2 fs (z − 1)/(z + 1), optionally prewarped.

    Parameters
    ----------
    K : control.StateSpace
        Continuous controller.
    fs_hz : float
        Loop rate (Hz); the result has ``dt = 1/fs_hz``.
    prewarp_hz : float, optional
        Frequency (Hz) at which K(z) matches K(s) exactly (e.g. the centre of the damping
        band); ``None``: plain bilinear transform.
    """
    import control
    import numpy as np

    kw = {}
    if prewarp_hz is not None:
        kw["prewarp_frequency"] = 2 * np.pi * float(prewarp_hz)
    return control.c2d(K, 1.0 / fs_hz, method="tustin", **kw)
