"""Shared pytest set-up."""

import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".venv" / "numba-cache"))
SHARED = ROOT.parent / "shared"
if str(ROOT) not in sys.path:  # `bench` and helper scripts importable in tests
    sys.path.insert(0, str(ROOT))


def pytest_report_header(config):
    """Say whether the browser tests (tests/browser) run or are skipped, and why."""
    from browserkit import report_header

    return report_header()


@pytest.fixture(scope="session")
def quick_demo(tmp_path_factory):
    """The output folder of one ``rigd demo --quick`` (the default, physics-grade plant), made
    once per test run and shared by its processes (``tests/sharedruns.py``): read by
    ``tests/design/test_demo_e2e.py`` and ``tests/browser/test_demo_page.py``. Tests only read
    it."""
    from sharedruns import shared_folder

    from rigd.cli import main

    def make(out):
        assert main(["demo", "--quick", "--out", str(out)]) == 0

    return shared_folder("demo-quick", make, tmp_path_factory)
