"""Numbers in explanations, each with its bound checked (issue 12, "checked numbers").

Shares are clamped to 0–100 %, frequencies are compared with the Nyquist frequency, and
lists of frequencies get enough significant digits to keep distinct values distinct
(0.06 and 0.12 Hz are not both "0.1 Hz"). Wording that only fits a rotor record (film,
piezo valves, gyroscopic) is chosen by :func:`is_rotor`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def share(x: float) -> str:
    """``x`` (0..1) as a percentage clamped to 0–100 %."""
    v = 0.0 if not math.isfinite(x) else min(max(float(x), 0.0), 1.0)
    return f"{100 * v:.0f} %"


def freqs(values: Sequence[float], digits: int = 3) -> list[str]:
    """Frequencies (Hz) with ≥ ``digits`` significant digits, more where needed so that
    distinct values print distinctly."""
    vals = [float(v) for v in values]
    for d in range(digits, 10):
        out = [f"{v:.{d}g}" for v in vals]
        clash = any(out[i] == out[j] and not math.isclose(vals[i], vals[j], rel_tol=1e-9)
                    for i in range(len(vals)) for j in range(i + 1, len(vals)))
        if not clash:
            return out
    return [repr(v) for v in vals]


def freq(f: float, fs: float) -> str:
    """One frequency in Hz with its bound: below the Nyquist frequency, else said so."""
    nyq = fs / 2.0
    if not math.isfinite(f) or f >= nyq:
        return f"above the Nyquist frequency ({freqs([nyq])[0]} Hz)"
    return f"{freqs([f])[0]} Hz"


def is_rotor(ctx) -> bool:
    """True for the rotor rig's sub-models (actuator, bearing), not for generic records."""
    return getattr(ctx, "submodel", "generic") in ("actuator", "bearing")
