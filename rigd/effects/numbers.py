"""Numbers in explanations, each with its bound checked (issue 12, "checked numbers").

Shares are clamped to 0–100 %, frequencies are compared with the Nyquist frequency, and
lists of frequencies get enough significant digits to keep distinct values distinct
(0.06 and 0.12 Hz are not both "0.1 Hz"), durations are ≥ 0 in the unit that reads best
(:func:`duration`). Wording that only fits a rotor record (film,
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

    def fmt(v: float, d: int) -> str:  # 1229 Hz, not 1.23e+03 Hz
        return f"{v:.0f}" if math.isfinite(v) and 10 ** d <= abs(v) < 1e15 else f"{v:.{d}g}"

    for d in range(digits, 10):
        out = [fmt(v, d) for v in vals]
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


def duration(t_s: float) -> str:
    """A duration ≥ 0 (s) in the unit that reads best: µs, ms or s (records run at any rate:
    a 30 s time constant is not "30000 ms"); 3 significant digits, whole numbers from 100.

    Raises
    ------
    ValueError
        Negative or non-finite (the caller words what a negative lag means).
    """
    t = float(t_s)
    if not math.isfinite(t) or t < 0:
        raise ValueError(f"a duration must be finite and >= 0, got {t_s!r}")
    v, unit = (t * 1e6, "µs") if t < 1e-3 else (t * 1e3, "ms") if t < 1.0 else (t, "s")
    return f"{v:.0f} {unit}" if v >= 100 else f"{v:.3g} {unit}"


def is_rotor(ctx) -> bool:
    """True for the rotor rig's sub-models (actuator, bearing), not for generic records."""
    return getattr(ctx, "submodel", "generic") in ("actuator", "bearing")
