"""Helpers for tests/design: model files built from the simulated plant's truth."""

from __future__ import annotations

import numpy as np

from rigd.ident.greybox.rotor import actuator_structure, bearing_structure
from rigd.ident.modelfile import ModelFile, Submodel
from rigd_drivers.sim import truth as simtruth


def truth_model_file(path, omega_rpm=4000.0, p_inj_bar=7.0, fs=5000.0):
    """Write a model file whose G_p is the simulated plant's truth (actuator: 2nd-order fit)."""
    from rigd_drivers.plant import physics as sp

    bm = sp.bearing_matrices(omega_rpm, p_inj_bar)
    bs = bearing_structure()
    tb = bs.pack(bm.K_id, bm.D_id, bm.B_id)
    acts = simtruth.actuator_fit(fs)
    K = np.diag([p1 * p2 for _, p1, p2 in acts])
    D = np.diag([p1 + p2 for _, p1, p2 in acts])
    B = np.diag([k * p1 * p2 for k, p1, p2 in acts])
    ast = actuator_structure()
    ta = ast.pack(K, D, B)
    mf = ModelFile(fs, {"bearing": Submodel("bearing", bs, tb, np.zeros_like(tb)),
                        "actuator": Submodel("actuator", ast, ta, np.zeros_like(ta))},
                   operating_point={"omega_rpm": omega_rpm, "p_inj_bar": p_inj_bar})
    mf.save(path)
    return path


def parallel_mode(G, f0, zeta, g):
    """G + a parallel mode at f0 (Hz) on each input with output gain g (extra_mode's block)."""
    from rigd.effects._linear import parallel

    w = 2 * np.pi * f0
    A, B, C = np.zeros((4, 4)), np.zeros((4, 2)), np.zeros((2, 4))
    for j in range(2):
        A[2 * j:2 * j + 2, 2 * j:2 * j + 2] = [[0.0, 1.0], [-w * w, -2 * zeta * w]]
        B[2 * j + 1, j] = w * w
        C[:, 2 * j] = g
    return parallel(G, A, B, C)
