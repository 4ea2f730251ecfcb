"""The words of a finding: effect + evidence code + domain -> one explanation.

Effects (rigd/effects) measure; they return an evidence code and the numbers behind it
(``Effect.evidence(ctx, sig) -> (code, evidence)``). This module turns them into the
``explanation`` string of the JSON and the report, in the words of the record's domain
(:mod:`rigd.diagnose.domain`): a rotor record hears of films, valves and gyroscopic
coupling; a mechanical structure of modes and resonances; a process plant of lags, time
constants and interactions between its inputs and outputs — never of stiffness,
resonances or a rotor. Experiments to run are worded by :mod:`rigd.diagnose.advice`.

Each entry of :data:`TEMPLATES` is keyed by ``(effect, code)`` and maps a domain (or
``"*"`` for all) to a function of the evidence dict. The evidence always carries
``share`` (the signature's share of the residual, 0..1) and ``fs`` (Hz).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

from rigd.diagnose.advice import closed_loop
from rigd.diagnose.domain import DOMAINS
from rigd.effects import numbers as N

Words = Callable[[dict[str, Any]], str]


def _explains(ev: dict[str, Any]) -> str:
    return f"explains {N.share(ev['share'])} of the residual"


def _hz_list(values: list[float]) -> str:
    return (", ".join(N.freqs(values)) + " Hz") if values else "none"


# --- extra_mode ---------------------------------------------------------------------------
def _mode_peak(ev: dict[str, Any], lacks: str, what: str) -> str:
    txt = N.freqs([ev["frequency_hz"], *ev["model_peaks_hz"]])
    model = (", ".join(txt[1:]) + " Hz") if ev["model_peaks_hz"] else "none"
    return (f"a narrow residual peak at {txt[0]} Hz (damping ≈ {ev['zeta']:.3g}), coherent "
            f"with the input, where the model has no {lacks} (model: {model}): {what}; "
            f"{_explains(ev)}")


# --- cross_coupling -----------------------------------------------------------------------
def _coupling(ev: dict[str, Any], domain: str) -> str:
    gyro = ev["antisymmetric"] and domain == "rotor"
    if gyro:
        what = "antisymmetric cross damping, the signature of gyroscopic coupling (Ω G ṗ)"
    elif domain in ("rotor", "mechanical"):
        what = "cross-coupled stiffness/damping between the axes"
    else:
        what = "an interaction between the paths (one input acting on another output)"
    om = (f" at Ω = {60 * ev['omega_hz']:.0f} rpm" if ev.get("omega_hz", 0) > 0
          and domain == "rotor" else "")
    other = "the other axis" if domain == "rotor" else "another input"
    return (f"the residual of {ev['output']} follows the motion of {other} "
            f"(correlation {ev['corr']:+.2f} with {ev['input']}){om}: {what}, missing from a "
            f"decoupled model; {_explains(ev)}")


# --- delay --------------------------------------------------------------------------------
def _lead(ev: dict[str, Any]) -> str:
    d = -ev["delay_samples"]
    return (f"the response leads the model by about {N.duration(d / ev['fs'])} "
            f"({N.freqs([d])[0]} samples at {ev['fs']:g} Hz): not a delay (a negative lag); "
            f"it {_explains(ev)}")


def _lag(ev: dict[str, Any], where: str) -> str:
    d = ev["delay_samples"]
    return (f"the response lags the model by about {N.duration(d / ev['fs'])} "
            f"({N.freqs([d])[0]} samples at {ev['fs']:g} Hz): a transport delay ({where}) "
            f"or sensor/computation latency; residual–input cross-correlation peaks at a "
            f"positive lag; it {_explains(ev)}")


def _base_delays(ev: dict[str, Any]) -> str:
    d = ev["delay_samples"]
    return (f"the model delays {ev['input']} by {N.freqs([d])[0]} samples "
            f"({N.duration(d / ev['fs'])} at {ev['fs']:g} Hz; per input: "
            f"{', '.join(str(v) for v in ev['delays_samples'])})")


def _base_lag(ev: dict[str, Any]) -> str:
    return (f"{_base_delays(ev)}, chosen from the data before the order: a transport delay or "
            f"a sensor/computation latency"
            + (f" (refitted without any delay it fits the held-out part "
               f"{ev['fit_points_lost']:.2f} points worse)" if "fit_points_lost" in ev else ""))


def _base_lag_not_paid(ev: dict[str, Any]) -> str:
    return (f"{_base_delays(ev)}, but refitted without any delay it fits the held-out part "
            f"only {max(ev['fit_points_lost'], 0.0):.2f} points worse (less than "
            f"{ev['min_points']:g}): the delay stands in for a lag of the dynamics (a slow "
            f"first response, e.g. lags in series), not a transport delay")


def _short_lag(ev: dict[str, Any], domain: str) -> str:
    d = max(ev["delay_samples"], 0.0)
    parts = ("valve or sensor dynamics" if domain == "rotor" else
             "actuator or sensor dynamics")
    return (f"a lag of {d:.2f} samples ({N.duration(d / ev['fs'])}) improves the fit, but a "
            f"delay shorter than {ev['min_samples']:g} sample cannot be told from unmodelled "
            f"fast dynamics at {ev['fs']:g} Hz: the model misses some high-frequency phase "
            f"lag (e.g. {parts} of higher order than the model), not a transport delay")


TEMPLATES: dict[tuple[str, str], dict[str, Words]] = {
    ("extra_mode", "no_peak"): {
        "process": lambda ev: "no narrow coherent peak in the residual away from the "
                              "model's dynamics",
        "*": lambda ev: "no narrow coherent peak in the residual away from the model's "
                        "resonances"},
    ("extra_mode", "peak"): {
        "process": lambda ev: _mode_peak(ev, "oscillation there",
                                         "an unmodelled oscillatory mode"),
        "*": lambda ev: _mode_peak(ev, "resonance", "an unmodelled structural mode")},
    ("cross_coupling", "coupling"): {d: (lambda ev, d=d: _coupling(ev, d))
                                     for d in ("rotor", "mechanical", "process", "generic")},
    ("delay", "lead"): {"*": _lead},
    ("delay", "delay.in_base"): {"*": _base_lag},
    ("delay", "delay.in_base_not_paid"): {"*": _base_lag_not_paid},
    ("delay", "lag"): {
        "rotor": lambda ev: _lag(ev, "valve to film force"),
        "*": lambda ev: _lag(ev, "input to response")},
    ("delay", "too_short"): {d: (lambda ev, d=d: _short_lag(ev, d))
                             for d in ("rotor", "mechanical", "process", "generic")},
}


# --- the domain-neutral entries -----------------------------------------------------------
def _static(ev: dict[str, Any]) -> str:
    site = ev["site"]
    if site == "input+output":
        bends = dict(zip(ev.get("channels", [ev["channel"]]), ev["bend_at_spread"]))
        parts = ", ".join(f"{c} by about {N.share(b)}" for c, b in bends.items())
        return (f"the error is a smooth function of the levels of the input and of the model "
                f"output: static curves at the input and at the output, bending {parts} at "
                f"their spreads (Hammerstein–Wiener form); {_explains(ev)}")
    signal = "the input" if site == "input" else "the model output"
    bend = max(ev["bend_at_spread"] or [0.0])
    form = "Hammerstein" if site == "input" else "Wiener"
    return (f"the error is a smooth function of the level of {signal} ({ev['channel']}): a "
            f"static curve at the {site} bending it by about {N.share(bend)} at its spread "
            f"({form} form); {_explains(ev)}")


def _static_state(ev: dict[str, Any]) -> str:
    share = ev["signal_share"].get(ev["channel"], 0.0)
    return (f"the error follows the levels of the signals inside the dynamics, not a curve "
            f"before or after them: a static curve of {ev['channel']} ({N.share(share)} of "
            f"the effect; every input and output carries one) fed back into the "
            f"{ev['states']} states (Lur'e form: a rate that depends on a level); "
            f"{_explains(ev)}")


def _friction(ev: dict[str, Any], domain: str) -> str:
    sense = "against" if ev["against_motion"] else "along"
    if domain == "process":
        return (f"the error jumps with the sign of the rate of change of {ev['output']}: an "
                f"opposition of constant size {sense} every change (a dead "
                f"band in an actuator: stiction); {_explains(ev)}")
    return (f"the error jumps with the sign of the velocity of {ev['output']}: a force of "
            f"constant size {sense} the motion (dry friction; the viscous part is the "
            f"model's damping); {_explains(ev)}")


def _integrator(ev: dict[str, Any], domain: str) -> str:
    if ev["in_base"] and not math.isfinite(ev["time_constant_s"]):  # an explicit integrator
        what = ("the model integrates: it has a pole at zero (an integrating plant), chosen "
                f"from the {N.duration(ev['estimation_seconds'])} it was fitted on")
    elif ev["in_base"]:
        what = (f"the model integrates: its slowest pole has a time constant of "
                f"{N.duration(ev['time_constant_s'])}, longer than the "
                f"{N.duration(ev['estimation_seconds'])} it was fitted on, so on this record "
                f"it is a pole at zero (an integrating plant)")
    else:
        what = (f"the error drifts like the integral of {ev['input']} on {ev['output']}: a "
                f"pole at zero the model lacks; {_explains(ev)}")
    return f"{what}; {closed_loop(ev, domain)}"


def _per_domain(words: Callable[[dict[str, Any], str], str]) -> dict[str, Words]:
    """One template per domain of ``words(ev, domain)``."""
    return {d: functools.partial(words, domain=d) for d in DOMAINS}


def _lag_path(ev: dict[str, Any]) -> str:
    return (f"the error follows a first-order lag of the input with a time constant of "
            f"about {N.duration(ev['time_constant_s'])}: a real pole (lag) the model lacks; "
            f"{_explains(ev)}")


NEUTRAL: dict[tuple[str, str], dict[str, Words]] = {
    ("static_nonlinearity", "static_nonlinearity.input"): {"*": _static},
    ("static_nonlinearity", "static_nonlinearity.output"): {"*": _static},
    ("static_nonlinearity", "static_nonlinearity.input_output"): {"*": _static},
    ("static_nonlinearity", "static_nonlinearity.state"): {"*": _static_state},
    ("friction", "friction.coulomb"): _per_domain(_friction),
    ("integrator", "integrator.in_base"): _per_domain(_integrator),
    ("integrator", "integrator.added"): _per_domain(_integrator),
    ("extra_dynamics", "extra_dynamics.real_pole"): {"*": _lag_path},
}
TEMPLATES.update(NEUTRAL)


def explanation(effect: str, code: str, evidence: dict[str, Any], domain: str) -> str:
    """The explanation of ``effect``'s evidence ``code`` in the words of ``domain``.

    Raises
    ------
    KeyError
        No wording for ``(effect, code)`` (a programming error: every code an effect emits
        has its words here; tests/diagnose/test_wording.py checks them).
    """
    by_domain = TEMPLATES[(effect, code)]
    words = by_domain.get(domain) or by_domain["*"]
    return words(evidence)


def has_words(effect: str, code: str) -> bool:
    return (effect, code) in TEMPLATES


# --- unexplained structure ----------------------------------------------------------------
def band_near_model(near_hz: list[float], domain: str) -> str:
    """A residual band around the model's own dynamics."""
    if domain == "process":
        return (f"around the model's dynamics ({_hz_list(near_hz)}): their shape depends on "
                "something the model lacks (a level- or load-dependent gain or time "
                "constant, or a second lag close to them); steps at two amplitudes would "
                "tell")
    return (f"around the model's resonance ({', '.join(N.freqs(near_hz))} Hz): its shape "
            "depends on something the model lacks (amplitude-dependent stiffness or "
            "damping outside the catalogue, or a second mode close to it); a stepped "
            "sine around it at two amplitudes would tell")


def band_narrow(domain: str) -> str:
    if domain == "process":
        return ("a narrow line away from the model's dynamics: an unmodelled oscillation "
                "(identify with a higher --order) or a periodic disturbance; record once "
                "with the excitation off to tell them apart")
    return ("a narrow line away from the model's resonances: an unmodelled mode "
            "(identify with a higher --order) or a periodic disturbance; record once "
            "with the excitation off to tell them apart")


def peaks_label(domain: str) -> str:
    """What the report's dashed lines at the model's oscillatory pole frequencies are."""
    return "model pole frequencies" if domain == "process" else "model resonances"
