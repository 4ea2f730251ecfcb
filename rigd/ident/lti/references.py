"""The black-box references as candidates of the base-model choice.

The yardstick (:mod:`rigd.ident.yardstick`) puts a plain ARX and a subspace model beside every
fit; a base model that a plain ARX beats on held-out data is a base-model choice that missed a
linear model the data support. So :func:`rigd.ident.lti.order.choose_base` lets the
references *themselves* compete: each is selected as the yardstick selects it, on the
estimation part alone (:func:`~rigd.ident.lti.arx.select_arx`: order and per-input delays by
the free-run fit on the estimation part's last third; :func:`~rigd.ident.lti.subspace.
select_subspace`: order likewise), and its poles become a general LTI model
(:class:`~rigd.ident.lti.statespace.StateSpaceModel`: gains, initial state and offsets by
least squares, :func:`~rigd.ident.lti.modal.gains_by_least_squares`), refined by output error
like the scan's candidates and judged by the same criterion.

An ARX model's poles are those of its A polynomial (the block companion matrix of
a_1 … a_na): the states an ARX model's observer form adds for the input delays (poles at 0)
are the StateSpaceModel's per-input delays instead. The ARX delay nk (the lag of the first b
coefficient) is a delay of nk − 1 samples behind a zero-order hold (a strictly proper plant)
and nk with a first-order hold, as :func:`rigd.ident.lti.order.input_delays`.
"""

from __future__ import annotations

import numpy as np

#: orders tried by the references here (the yardstick's ARX orders; subspace likewise up to
#: the most states a base model gets)
ARX_ORDERS = tuple(range(1, 11)) + (15, 20, 30)
SUBSPACE_ORDERS = tuple(range(1, 11)) + (12, 16, 20, 25, 30)


def arx_companion(a: np.ndarray) -> np.ndarray:
    """The block companion matrix of an ARX model's A polynomial, ``a`` (na, ny, ny) =
    a_1 … a_na: its na·ny eigenvalues are the model's poles."""
    na, ny = a.shape[0], a.shape[1]
    A = np.zeros((na * ny, na * ny))
    for k in range(na):
        A[k * ny:(k + 1) * ny, :ny] = -a[k]
        if k + 1 < na:
            A[k * ny:(k + 1) * ny, (k + 1) * ny:(k + 2) * ny] = np.eye(ny)
    return A


def reference_models(d_est, hold: str) -> list[tuple[str, np.ndarray, list[int]]]:
    """(name, discrete A, per-input delays for ``hold``) of the ARX and subspace references
    selected on the estimation data ``d_est`` alone (module docstring); a reference that
    cannot be fitted is left out."""
    from rigd.ident.lti.arx import select_arx
    from rigd.ident.lti.subspace import select_subspace

    u, y = np.asarray(d_est.u, float), np.asarray(d_est.y, float)
    fs = float(d_est.fs)
    out = []
    try:
        sel = select_arx(u, y, ARX_ORDERS, fs=fs)
        delays = [max(int(k) - 1, 0) if hold == "zoh" else int(k) for k in sel.nk]
        if sel.model.na > 0:
            out.append(("arx", arx_companion(sel.model.a), delays))
    except (ValueError, np.linalg.LinAlgError):
        pass
    try:
        res, _ = select_subspace(u, y, SUBSPACE_ORDERS, fs=fs)
        out.append(("subspace", np.asarray(res.model.A, float), [0] * u.shape[1]))
    except (ValueError, np.linalg.LinAlgError):
        pass
    return out
