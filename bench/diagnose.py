"""Benchmarks: ``diagnose_60s_s`` — full diagnosis of a 60 s bearing record at 5 kHz
(300,000 samples; analysed on a 40,000-sample window, see rigd.diagnose.diagnosis.MAX_SAMPLES);
``diagnose_generic_order_auto_s`` — full diagnosis, order chosen from the data
(``--order auto``), of a 40,000-sample record of the 3-mass flexible chain
(tests/diagnose/benchmarks.py; target ≤ 20 s); ``diagnose_mimo_s`` — full diagnosis, order
auto, of an 8,000-sample 2-input record of a 3-mode structure (tests/gen
``structure_2in_3modes``; target ≤ 30 s); ``fit_lti_exact_columns_s`` /
``fit_lti_differences_s`` — the output-error fit of a 13-state general LTI model on 40,000
samples (the base refinement every generic diagnosis runs) with the exact columns of the
parameters it is linear in (rigd.ident.jacobian) and with forward differences only, and
whether both took the same steps."""

from __future__ import annotations

import sys
import time
from pathlib import Path


def mimo() -> dict:
    """``diagnose_mimo_s``: the 2-input, 8,000-sample record, ``--order auto``."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import numpy as np

    from rigd.data.record import Record
    from rigd.diagnose.diagnosis import diagnose_record
    from tests.gen import linear

    g = linear.structure_2in_3modes(seed=0, n=8000)
    head, data = g.columns()
    rec = Record({h: np.ascontiguousarray(data[:, i]) for i, h in enumerate(head)}, g.fs,
                 {"inputs": g.inputs, "outputs": g.outputs}, "bench-mimo")
    t0 = time.perf_counter()
    d = diagnose_record(rec)
    dt = time.perf_counter() - t0
    part = d.parts[0]
    return {"diagnose_mimo_s": round(dt, 2), "diagnose_mimo_n": int(rec.n),
            "diagnose_mimo_modes": (part.order or {}).get("modes"),
            "diagnose_mimo_true_modes": len(g.truth["modes"]),
            "diagnose_mimo_fit": round(float(np.mean(part.fit_percent)), 2)}


def lti_fit() -> dict:
    """``fit_lti_*``: one output-error fit, exact linear columns against differences only."""
    import numpy as np

    from rigd.ident.iddata import IdData
    from rigd.ident.lti.statespace import StateSpaceModel
    from rigd.ident.pem import fit

    rng = np.random.default_rng(0)
    n, fs = 40_000, 100.0
    m = StateSpaceModel(["u"], ["y"], fs, n_complex=6, n_real=1, hold="foh")
    m.set_record(n)
    lam = [complex(-0.5 * (k + 1), 3.0 * (k + 1)) for k in range(6)] + [complex(-2.0, 0.0)]
    th = m.pack(lam, rng.standard_normal((13, 1)), np.ones((1, 13)))
    u = rng.standard_normal((n, 1))
    y = m.simulate(th, IdData(u, np.zeros((n, 1)), fs, ["u"], ["y"]))
    d = IdData(u, y + 0.05 * np.std(y) * rng.standard_normal((n, 1)), fs, ["u"], ["y"])
    th0 = th * (1 + 0.02 * rng.standard_normal(th.size))
    fit(m, d.slice(0, 500), method="oe", theta0=th0)   # compiled kernels warm
    t0 = time.perf_counter()
    exact = fit(m, d, method="oe", theta0=th0)
    t_exact = time.perf_counter() - t0
    sens = StateSpaceModel.output_sensitivities
    try:
        del StateSpaceModel.output_sensitivities
        t0 = time.perf_counter()
        diff = fit(m, d, method="oe", theta0=th0)
        t_diff = time.perf_counter() - t0
    finally:
        StateSpaceModel.output_sensitivities = sens
    return {"fit_lti_exact_columns_s": round(t_exact, 2),
            "fit_lti_differences_s": round(t_diff, 2),
            "fit_lti_same_steps": bool(exact.nfev == diff.nfev and abs(exact.cost - diff.cost)
                                       <= 1e-8 * diff.cost),
            "fit_lti_parameters": len(m.names)}


def run() -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "diagnose"))
    import plant
    from rigd.data.record import Record
    from rigd.diagnose.diagnosis import diagnose_record

    d = plant.bearing(["cubic_stiffness"], seed=0, seconds=60.0)
    rec = Record({"u_x": d.u[:, 0], "u_y": d.u[:, 1], "e_x": d.y[:, 0], "e_y": d.y[:, 1]},
                 d.fs, {"omega_rpm": 0.0, "p_inj_bar": 4.0}, "bench-60s")
    t0 = time.perf_counter()
    diag = diagnose_record(rec, submodels=["bearing"])
    dt = time.perf_counter() - t0
    top = diag.parts[0].findings[0]
    import benchmarks

    gen = benchmarks.three_mode(seed=0, n=40_000)
    t0 = time.perf_counter()
    dg = diagnose_record(gen)
    dt_g = time.perf_counter() - t0
    return {"diagnose_60s_s": round(dt, 2), "diagnose_60s_top": top.effect,
            "diagnose_60s_n": int(rec.n),
            "diagnose_generic_order_auto_s": round(dt_g, 2),
            "diagnose_generic_order_auto_modes": int(dg.parts[0].order["modes"]),
            "diagnose_generic_order_auto_fit": round(float(dg.parts[0].fit_percent), 2),
            "diagnose_generic_order_auto_n": int(gen.n), **mimo(), **lti_fit()}
