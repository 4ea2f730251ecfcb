"""Reduction of the full-order K∞(s) by balanced truncation (paper Sec. 5: 24 → 4 states).

Gramian-based input/output balancing (SLICOT AB09AD through python-control ``balred``). An
unstable controller is split into its stable and unstable parts and only the stable part is
truncated (AB09MD). The truncation is done in the same frequency-scaled time unit as the
synthesis (:data:`rigd.design.hinf.OMEGA_SCALE`) for conditioning.
"""

from __future__ import annotations

import numpy as np

from rigd.design.hinf import OMEGA_SCALE


def hankel_singular_values(K) -> np.ndarray:
    """Hankel singular values of K (descending; in the scaled time unit, which leaves them
    unchanged). Empty when K is not stable.

    Computed by SLICOT AB09AD (square-root method, Cholesky factors of the Gramians), which
    stays accurate where ``control.hsvd`` (eigenvalues of Wc·Wo) returns NaN for the
    ill-conditioned Gramians of weighted H∞ controllers. All n values are asked for
    (``nr=n``): on a non-minimal K SLICOT says that it set the order of its (unused)
    truncation to the minimal one, a remark on the call, not on the values (the trailing
    ones are then ≈ 0); it is not passed on to the user.
    """
    import warnings

    from slycot import ab09ad
    from slycot.exceptions import SlycotResultWarning

    w = OMEGA_SCALE
    A, B, C = np.asarray(K.A) / w, np.asarray(K.B) / w, np.asarray(K.C)
    n = A.shape[0]
    if n == 0 or not np.all(np.linalg.eigvals(A).real < 0):
        return np.array([])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SlycotResultWarning)
        *_, hsv = ab09ad("C", "B", "N", n, B.shape[1], C.shape[0], A.copy(), B.copy(),
                         C.copy(), nr=n)
    return np.sort(np.asarray(hsv, dtype=float))[::-1]


def reduce_controller(K, order: int, method: str = "truncate"):
    """Balanced truncation of a continuous controller to ``order`` states.

    Parameters
    ----------
    K : control.StateSpace
        Continuous K∞(s).
    order : int
        Wanted number of states (at least the number of unstable poles of K).
    method : {"truncate", "matchdc"}
        ``truncate``: plain balanced truncation (good at high frequency, keeps D);
        ``matchdc``: singular perturbation (matches the DC gain).

    Returns
    -------
    control.StateSpace
        Reduced K∞(s); K itself when ``order`` >= its order.
    """
    import control

    if order >= K.nstates:
        return K
    w = OMEGA_SCALE
    Ks = control.ss(K.A / w, K.B / w, K.C, K.D)
    Kr = control.balred(Ks, order, method=method)
    return control.ss(Kr.A * w, Kr.B * w, Kr.C, Kr.D)
