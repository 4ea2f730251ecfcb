"""What to record next: the ``why`` and ``experiment`` of an effect a record cannot show.

Effects say *that* a record cannot show them and give an evidence code and numbers
(:class:`rigd.effects.context.CannotReveal` ``code``/``evidence``); this module words it for
the record's domain (:mod:`rigd.diagnose.domain`). Durations and amplitudes are computed from
the record's own rate and the base model's time constants; a rotor experiment file
(``config/experiments/*.yaml``) is named only for a record that came from rigd's rotor rig.
"""

from __future__ import annotations

from typing import Any

from rigd.effects import numbers as N

#: the rig's experiment with multi-level steps and long holds (rotor records only)
ROTOR_MULTILEVEL = "config/experiments/multilevel_slow.yaml"


def holds(ctx_fs: float, taus: list[float]) -> tuple[float, float]:
    """Step holds (s) long enough to show slow behaviour after a step: from one to ten of the
    base model's slowest time constant (at least 20 samples), else 20–200 samples."""
    t = max(taus) if taus else 0.0
    lo = max(t, 20.0 / ctx_fs)
    return lo, 10.0 * lo


def _multilevel(ev: dict[str, Any], domain: str) -> str:
    if domain == "rotor":
        return f"multi-level PRBS or a slow triangle, e.g. {ROTOR_MULTILEVEL}"
    lo, hi = holds(ev["fs"], ev.get("time_constants_s", []))
    return (f"several input levels, each held {N.duration(lo)}–{N.duration(hi)} (one to ten "
            "of the model's slowest time constant), or a slow triangle over the input range")


def cannot_reveal(effect: str, code: str, ev: dict[str, Any], domain: str
                  ) -> tuple[str, str]:
    """``(why, experiment)`` for ``effect``'s code in the words of ``domain``."""
    if effect == "cross_coupling":
        return _coupling(code, ev, domain)
    if effect == "hysteresis" and code == "few_levels":
        return ev["why"], f"re-run with multi-level excitation ({_multilevel(ev, domain)})"
    if effect == "creep":
        return ev["why"], _creep(ev, domain)
    raise KeyError((effect, code))


def _coupling(code: str, ev: dict[str, Any], domain: str) -> tuple[str, str]:
    nu, ny = ev["nu"], ev["ny"]
    if code == "same_signal":
        which = "axes" if domain == "rotor" else "inputs"
        return (f"the {which} were excited with the same signal, so direct and cross paths "
                "cannot be told apart",
                "re-run with independent PRBS on each axis" if domain == "rotor" else
                "re-run with each input excited by its own, independent signal")
    if domain == "rotor":
        return "the record has a single axis", "record both axes (two inputs, two outputs)"
    if nu < 2:
        why = "the record has a single input"
    elif ny < 2:
        why = f"the record has {nu} inputs but a single output"
    else:
        why = (f"the record has {nu} inputs and {ny} outputs: the cross-coupling model pairs "
               "each input with one output")
    return why, ("record as many outputs as inputs, each input excited independently "
                 "(each output's own input and the others' acting on it)")


def _creep(ev: dict[str, Any], domain: str) -> str:
    if domain == "rotor":
        return (f"re-run with steps held for 0.05–0.5 s (multi-level with long holds, "
                f"{ROTOR_MULTILEVEL}) and a record several times longer than the creep's "
                "slow time constant")
    lo, hi = holds(ev["fs"], ev.get("time_constants_s", []))
    return (f"re-run with steps held for {N.duration(lo)}–{N.duration(hi)} (multi-level, one "
            "to ten of the model's slowest time constant) and a record several times "
            "longer than the creep's slow time constant")
