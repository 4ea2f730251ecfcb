"""Plain Python values for JSON and YAML writers (a leaf: numpy only).

:func:`plain` is the one conversion used for model files (YAML), the ``--json`` outputs, the
control socket (JSON lines) and HDF5 attributes read back: numpy scalars and arrays become
Python numbers and lists, tuples become lists, mapping keys strings, bytes UTF-8 text, and
anything else that JSON cannot hold its ``str``.

NaN policy (one, everywhere): a non-finite float (NaN, ±inf) becomes ``None`` — ``null`` in
JSON and YAML. Strict JSON has no NaN, and a reader in any language understands ``null`` as
"no value"; writers then never emit ``NaN`` / ``.nan``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def plain(value: Any) -> Any:
    """``value`` as plain Python (dict, list, str, int, float, bool, None); see module doc."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (str, int, bool)):
        return value
    return str(value)
