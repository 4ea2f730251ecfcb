"""Where the browser tests find Chromium and its driver (import as ``from browserkit import
...``; shared by ``tests/conftest.py``'s report header and ``tests/browser/conftest.py``).

The browser tests drive Debian's ``chromium`` through ``chromium-driver`` (selenium 4, no
browser download at run time); ``.ci/run`` installs both with apt-get when absent.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from functools import cache
from pathlib import Path

from testpaths import ROOT

ARTIFACTS = ROOT / "test-artifacts"
SCREENSHOTS = ARTIFACTS / "screenshots"


def _first_executable(*candidates: str | None) -> str | None:
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    return None


@cache
def find_chromium() -> tuple[str | None, str | None, str | None]:
    """``(chromium, chromedriver, version)``; a missing part is ``None``.

    ``RIGD_CHROMIUM`` / ``RIGD_CHROMEDRIVER`` override the paths (e.g. to check the skip).
    """
    env_c, env_d = os.environ.get("RIGD_CHROMIUM"), os.environ.get("RIGD_CHROMEDRIVER")
    chromium = (_first_executable(env_c) if env_c is not None else _first_executable(
        "/usr/bin/chromium", shutil.which("chromium"), shutil.which("chromium-browser")))
    driver = (_first_executable(env_d) if env_d is not None else _first_executable(
        "/usr/bin/chromedriver", shutil.which("chromedriver")))
    version = None
    if chromium and driver:
        try:
            out = subprocess.run([driver, "--version"], capture_output=True, text=True,
                                 timeout=30).stdout.split()
            version = out[1] if len(out) > 1 else "?"
        except (OSError, subprocess.SubprocessError):
            driver = None
    return chromium, driver, version


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
