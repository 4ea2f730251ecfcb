"""Benchmarks: ``diagnose_60s_s`` — full diagnosis of a 60 s bearing record at 5 kHz
(300,000 samples; analysed on a 40,000-sample window, see rigd.diagnose.diagnosis.MAX_SAMPLES);
``diagnose_generic_order_auto_s`` — full diagnosis, order chosen from the data
(``--order auto``), of a 40,000-sample record of the 3-mass flexible chain
(tests/diagnose/benchmarks.py; target ≤ 20 s); ``diagnose_mimo_s`` — full diagnosis, order
auto, of an 8,000-sample 2-input record of a 3-mode structure (tests/gen
``structure_2in_3modes``; target ≤ 30 s)."""

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
            "diagnose_generic_order_auto_n": int(gen.n), **mimo()}
