"""Reading a run directory's ``manifest.json`` (format ``rigd_manifest: 1``).

The format and the writer are in :mod:`rigd.experiments.manifest`; reading lives here, with
the other data readers, so that identification (``rigd identify RUN_DIR``) reads run
directories without importing the experiment runner.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rigd.errors import InputError

#: file name of the manifest inside a run directory
MANIFEST = "manifest.json"


def read_manifest(run_dir: str | Path) -> dict[str, Any]:
    """Load a run directory's manifest (InputError if missing or not a manifest)."""
    p = Path(run_dir)
    if p.is_dir():
        p = p / MANIFEST
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("no manifest.json (not a run directory)", str(p)) from None
    except (OSError, ValueError) as exc:
        raise InputError(f"unreadable manifest: {exc}", str(p)) from None
    if not isinstance(data, dict) or data.get("rigd_manifest") != 1:
        raise InputError("not a rigd manifest (rigd_manifest: 1 missing)", str(p))
    return data
