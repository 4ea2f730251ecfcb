"""Paths for tests; import as ``from testpaths import ROOT, SHARED`` (unique module name:
``from conftest import ...`` is ambiguous once several test folders have a conftest.py)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# ../shared beside the checkout: /work/main -> /work/shared; a worktree /work/wt/NAME too
SHARED = next((p / "shared" for p in ROOT.parents if (p / "shared" / "data").is_dir()),
              ROOT.parent / "shared")
