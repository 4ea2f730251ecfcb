"""Benchmark: bearing model (Eqs. 5-7, 20 parameters) identified by PEM on 30,000 samples.

``identify_bearing_s``: wall time of one complete fit from the automatic initial guess
(numba kernels compiled beforehand, as they are cached on disk after the first run).
"""

from __future__ import annotations

import time

import numpy as np


def _record(n: int = 30000, seed: int = 0):
    from rigd.ident.iddata import IdData
    from rigd.ident.simulate import simulate_mechanical

    rng = np.random.default_rng(seed)
    w1, w2 = 2 * np.pi * 110.0, 2 * np.pi * 160.0
    K = np.array([[w1 ** 2, 0.1 * w1 * w2], [-0.05 * w1 * w2, w2 ** 2]])
    D = np.array([[2 * 0.05 * w1, 5.0], [-3.0, 2 * 0.04 * w2]])
    B = K @ np.array([[5.0, 0.5], [-0.3, 4.0]])
    u = np.repeat(np.sign(rng.standard_normal((n // 2 + 1, 2))), 2, axis=0)[:n]
    y = simulate_mechanical(K, D, B, np.zeros(4), u, 5000.0, hold="foh")
    y += 0.02 * y.std(0) * rng.standard_normal(y.shape)
    return IdData(u, y, 5000.0, ["u_x", "u_y"], ["e_x", "e_y"])


def run() -> dict:
    from rigd.ident.greybox.rotor import bearing_structure
    from rigd.ident.pem import fit

    data = _record()
    S = bearing_structure("foh")
    fit(S, data.slice(0, 2000))  # compile / load the numba cache
    t = time.perf_counter()
    res = fit(S, data)
    dt = time.perf_counter() - t
    return {"identify_bearing_s": round(dt, 3),
            "identify_bearing_fit_percent": round(float(np.mean(res.fit_percent)), 2),
            "identify_bearing_nfev": res.nfev}


if __name__ == "__main__":  # pragma: no cover
    print(run())
