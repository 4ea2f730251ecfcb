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
    if effect == "delay" and code == "no_band":
        return _no_band(ev, domain)
    words = NEUTRAL.get((effect, code))
    if words is not None:
        return words(ev, domain)
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


def closed_loop(ev: dict[str, Any], domain: str = "generic") -> str:
    """What to do about an integrating plant (advice code ``identify_closed_loop``): the
    input reacts to the output under feedback, so an open-loop fit of the plant is biased.

    On a ``mechanical`` record (a structure under a shaker) an integrating path is a free
    rigid-body motion or a suspension mode below the band, and the advice is a modal
    tester's: a soft suspension, or the rigid-body mode in the model; a closed loop only when
    the input is seen to react to the output."""
    seen = ("the input reacts to what the model cannot explain (closed-loop data): "
            if ev.get("feedback_suspected") else "")
    if domain == "mechanical" and not ev.get("feedback_suspected"):
        return ("a free (rigid-body) motion or a suspension mode below the excited band: "
                "support the structure on a soft suspension whose modes lie well below the "
                "first flexible mode (a fifth of its frequency or less), or measure with the "
                "structure's own support and keep the rigid-body mode in the model")
    return (f"{seen}identify it in closed loop — the controller's reference as the input and "
            "the controller in the model — or record it in open loop around an operating "
            "point held by a slow outer loop")


def broadband(domain: str) -> str:
    """An excitation with power up to half the sample rate, in the words of ``domain``."""
    if domain == "rotor":
        return "re-run with a broadband excitation (PRBS at the loop rate)"
    if domain == "mechanical":
        return ("re-run with a force that has power up to half the sample rate: a random or "
                "multisine shaker signal over the whole band, or an impact hammer")
    return "re-run with a broadband excitation (a PRBS at the sample rate)"


# --- the domain-neutral entries -----------------------------------------------------------
def _detect(ev: dict[str, Any]) -> str:
    """The detectability's numbers (rigd.effects.detectability.Detectability) in words."""
    d = ev["detectability"]
    return (f"{100 * d['absorbed']:.3g} % of it would be absorbed by the base model; the rest "
            f"is {d['snr']:.2g}× the residual level, {d['fit_points']:.2g} fit points, F test "
            f"p = {d['p']:.2g}")


def _slowest(ev: dict[str, Any]) -> float:
    """The base model's slowest time constant (s), else 20 samples."""
    taus = ev.get("time_constants_s") or []
    return max(taus) if taus else 20.0 / ev["fs"]


def _unseen(what: str, ev: dict[str, Any], where: str = "") -> str:
    """Why: ``what`` (the effect at its nominal size) would not show on this record."""
    return (f"{what.format(share=N.share(ev['nominal_share']))} would not show on this "
            f"record{where} ({_detect(ev)})")


def _static_curve(ev: dict[str, Any], domain: str) -> tuple[str, str]:
    return (_unseen("a static curve bending the input or the output by {share} of its "
                    "spread", ev),
            f"re-run with an input that visits many levels over the whole operating range: "
            f"{_multilevel(ev, domain)}")


def _integrating(ev: dict[str, Any], domain: str) -> tuple[str, str]:
    lo, hi = holds(ev["fs"], ev.get("time_constants_s", []))
    length = max(10.0 * hi, 3.0 * ev["record_seconds"])
    return (_unseen("an integrating path adding {share} of the output's spread", ev),
            f"re-run for at least {N.duration(length)} (this record: "
            f"{N.duration(ev['record_seconds'])}) with slower input changes — levels held "
            f"{N.duration(lo)}–{N.duration(hi)} — or identify in closed loop")


def _lag_path(ev: dict[str, Any], domain: str) -> tuple[str, str]:
    lo, hi = holds(ev["fs"], ev.get("time_constants_s", []))
    return (_unseen("a first-order lag path adding {share} of the output's spread", ev,
                    " at any time constant tried, at best"),
            f"re-run with steps held {N.duration(lo)}–{N.duration(hi)}, longer than the "
            f"suspected lag, and a record of at least {N.duration(10 * hi)}")


def _no_reversal(ev: dict[str, Any], domain: str) -> tuple[str, str]:
    t = _slowest(ev)
    share = N.share(ev["min_each_way"])
    if domain == "process":
        why = (f"the output never turns back (each direction of change under {share} of "
               "the record): an opposition of constant size against every change cannot be "
               "told from an offset")
    else:
        why = (f"the motion never reverses (each direction under {share} of the record): a "
               "force of constant size against the motion cannot be told from an offset")
    return why, (f"re-run with an input that moves back and forth: a slow triangle or a "
                 f"low-frequency multisine with periods of {N.duration(2 * t)}–"
                 f"{N.duration(20 * t)} (two to twenty of the model's slowest time constant)")


def _no_band(ev: dict[str, Any], domain: str) -> tuple[str, str]:
    return ("the input has no power above 5 % of the sample rate, so a delay is "
            "indistinguishable from a gain", broadband(domain))


NEUTRAL = {
    ("static_nonlinearity", "too_small"): _static_curve,
    ("integrator", "too_small"): _integrating,
    ("extra_dynamics", "too_small"): _lag_path,
    ("friction", "no_reversal"): _no_reversal,
}
