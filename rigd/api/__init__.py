"""rigd's Python API: the modelling workflow and experiments for scripts and notebooks.

    >>> import rigd.api as rigd
    >>> res = rigd.run_experiment({"kind": "prbs", ...}, out="runs/prbs")   # lock-step sim
    >>> rec = rigd.load(next(res.run_dir.glob("*.h5")))
    >>> idf = rigd.identify(rec, "both")            # actuator (Eqs. 8-10) + bearing (5-7)
    >>> rigd.compare(idf, rec, part="validation").fit_percent
    >>> rigd.diagnose(rec).significant               # missing physical effects
    >>> idf2 = rigd.identify(rec, "both", add=["delay"])
    >>> K = rigd.design(idf2.save("G_p.yaml"), "config/design.yaml", "K.yaml").K

Every ``rigd`` command is a thin layer over these functions (it parses arguments, calls one of
them and prints); the walk-through is docs/api.md. Models and controllers are python-control
``StateSpace`` objects, records :class:`~rigd.data.record.Record`, results small dataclasses
whose ``summary()`` is the command's ``--json`` object. Bad input raises
:class:`rigd.errors.InputError` with one line naming what and where.

The sub-modules import numpy/scipy/control only when a function runs, so importing this
package is cheap.
"""

from __future__ import annotations

from rigd.api.data import apply_range, describe_source, load, parse_fs, parse_range
from rigd.api.design import Design, design
from rigd.api.experiment import (
                                 ExperimentResult,
                                 connect_daemon,
                                 run_experiment,
                                 run_experiment_daemon,
)
from rigd.api.impact import analyze_impact
from rigd.api.modelling import (
                                 ComparisonResult,
                                 DiagnosisResult,
                                 Identification,
                                 compare,
                                 diagnose,
                                 identify,
                                 identify_sweep,
                                 parse_effects,
)

__all__ = ["ComparisonResult", "Design", "DiagnosisResult", "ExperimentResult",
           "Identification", "analyze_impact", "apply_range", "compare", "connect_daemon",
           "describe_source", "design", "diagnose", "identify", "identify_sweep", "load",
           "parse_effects", "parse_fs", "parse_range", "run_experiment",
           "run_experiment_daemon"]
