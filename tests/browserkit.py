"""Where the browser tests find Chromium and its driver (import as ``from browserkit import
...``; shared by ``tests/conftest.py``'s report header and ``tests/browser/conftest.py``).

The browser tests drive Debian's ``chromium`` through ``chromium-driver`` (selenium 4, no
browser download at run time); ``.ci/run`` installs both with apt-get when absent.
"""

from __future__ import annotations

from pathlib import Path

from testpaths import ROOT

from bench.chromium import find_chromium

__all__ = ["find_chromium", "report_header", "screenshot_path", "skip_reason"]

ARTIFACTS = ROOT / "test-artifacts"
SCREENSHOTS = ARTIFACTS / "screenshots"


def skip_reason() -> str | None:
    """Why the browser tests cannot run here, or ``None`` when they can."""
    chromium, driver, _ = find_chromium()
    if chromium and driver:
        return None
    missing = " and ".join(n for n, p in (("chromium", chromium), ("chromedriver", driver))
                           if not p)
    return (f"browser tests: SKIPPED ({missing} not found; .ci/run installs chromium and "
            "chromium-driver with apt-get)")


def report_header() -> str:
    reason = skip_reason()
    if reason:
        return reason
    chromium, driver, version = find_chromium()
    return f"browser tests: run with chromium {version} ({chromium}, {driver})"


def screenshot_path(name: str) -> Path:
    """``test-artifacts/screenshots/<name>.png`` (folder created; ``name`` a plain word)."""
    if not name or "/" in name or "\\" in name or name.startswith("."):
        raise ValueError(f"screenshot name {name!r}: a plain file name without extension")
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    return SCREENSHOTS / f"{name}.png"
