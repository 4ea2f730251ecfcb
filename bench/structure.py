"""Benchmarks: a measured structure under a shaker, as a modal tester records it.

A 3-accelerometer × 70,000-sample record (400 Hz, 175 s: two periods of a 35,000-sample
random-phase multisine over 3–40 Hz) of the five-mode jointed structure of
``tests/gen/joint.py`` (an Iwan joint in the first mode's load path), at twice the base
force level:

* ``structure_diagnose_s`` — ``rigd diagnose`` of it with the defaults (the base's order and
  delays chosen from the data, every offered effect screened and the best refitted; the
  analysis window is ``structure_diagnose_analysed_n`` samples, see
  ``rigd.ident.pipeline.MAX_SAMPLES``); target ≤ 120 s. ``structure_diagnose_top`` is the
  effect it names, ``structure_diagnose_top_hz`` the frequency of the mode it sits at
  (``structure_joint_hz``: the joint mode's apparent frequency at this force level, read
  from the record's own frequency response, between the stuck and the slipped joint's).
* ``structure_identify_s`` — ``rigd identify`` of the same record with the defaults (the
  linear base, order from the data); target ≤ 60 s; ``structure_identify_fit`` its
  held-out fit (%, mean over the outputs).

Both are timed after one small diagnosis of a short record of the same kind (compiled
kernels loaded from numba's cache, as every ``rigd`` command after the first).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

N_PERIOD = 35_000
LEVEL = 2.0


def _record(n_period: int, periods: int):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.gen import joint

    g = joint.joint_structure(level=LEVEL, n=n_period, periods=periods, n_outputs=3, seed=0)
    return g, g.record(), joint.mode_near(g, 1.05 * g.truth["joint_f_hz"])[0]


def run() -> dict:
    import numpy as np

    from rigd.diagnose.diagnosis import diagnose_record
    from rigd.ident.workflow import identify_record

    _, small, _ = _record(2048, 2)
    diagnose_record(small)                       # kernels loaded, imports done
    g, rec, f_joint = _record(N_PERIOD, 2)
    t0 = time.perf_counter()
    d = diagnose_record(rec)
    t_diag = time.perf_counter() - t0
    part = d.parts[0]
    top = part.findings[0] if part.findings else None
    top_hz = top.evidence.get("mode_hz") if top is not None else None
    t0 = time.perf_counter()
    mf = identify_record(rec)
    t_id = time.perf_counter() - t0
    sub = next(iter(mf.submodels.values()))
    return {"structure_n": int(rec.n), "structure_outputs": len(g.outputs),
            "structure_joint_hz": round(float(f_joint), 3),
            "structure_diagnose_s": round(t_diag, 1),
            "structure_diagnose_analysed_n": int(part.window[1] - part.window[0]),
            "structure_diagnose_top": top.effect if top is not None else None,
            "structure_diagnose_top_hz": None if top_hz is None else round(float(top_hz), 3),
            "structure_identify_s": round(t_id, 1),
            "structure_identify_fit": round(float(sub.fit_percent["validation_mean"]), 2),
            "structure_diagnose_fit": round(float(np.mean(part.fit_percent)), 2)}
