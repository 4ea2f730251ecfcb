"""Shared set-up of the diagnosis tests: the simulated rig helper (plant.py) importable, and
the default diagnoses that tests of several modules assert on, made once per test run
(tests/sharedruns.py; each test gets its own copy)."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))  # the simulated rig helper (plant.py)


def _shared_diagnosis(name, record, tmp_path_factory):
    from sharedruns import shared_value

    from rigd.diagnose.diagnosis import diagnose_record

    return record(), shared_value(f"diagnosis-{name}", lambda: diagnose_record(record()),
                                  tmp_path_factory)


@pytest.fixture(scope="session")
def duffing_diagnosis(tmp_path_factory):
    """``(record, default diagnosis)`` of the generated Duffing record ``benchmarks.duffing(seed=0,
    n=3000)``: read by test_benchmark_records.py (cubic stiffness named) and
    test_metamorphic.py (the reference of its invariance cases)."""
    import benchmarks as B

    return _shared_diagnosis("duffing-0-3000", lambda: B.duffing(seed=0, n=3000),
                             tmp_path_factory)


@pytest.fixture(scope="session")
def bouc_wen_diagnosis(tmp_path_factory):
    """``(record, default diagnosis)`` of the Bouc–Wen benchmark record
    ``benchmarks.bouc_wen(seed=0, variant=0)``: read by test_benchmark_records.py (hysteresis
    at the restoring force named) and test_metamorphic.py (the reference of its invariance
    case)."""
    import benchmarks as B

    return _shared_diagnosis("bouc-wen-0-0", lambda: B.bouc_wen(seed=0, variant=0),
                             tmp_path_factory)
