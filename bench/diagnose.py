"""Benchmarks: ``diagnose_60s_s`` — full diagnosis of a 60 s bearing record at 5 kHz
(300,000 samples; analysed on a 40,000-sample window, see rigd.diagnose.diagnosis.MAX_SAMPLES);
``diagnose_generic_order_auto_s`` — full diagnosis, order chosen from the data
(``--order auto``), of a 40,000-sample record of the 3-mass flexible chain
(tests/diagnose/benchmarks.py; target ≤ 20 s)."""

from __future__ import annotations

import sys
import time
from pathlib import Path


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
            "diagnose_generic_order_auto_n": int(gen.n)}
