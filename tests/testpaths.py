"""Paths for tests; import as ``from testpaths import ROOT, SHARED`` (unique module name:
``from conftest import ...`` is ambiguous once several test folders have a conftest.py)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
