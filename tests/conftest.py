"""Shared pytest set-up."""

import os
import sys
from pathlib import Path

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
