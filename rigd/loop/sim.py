"""``simulate_record``: a lock-step loop on the simulated plant, returning the record in memory.

For tests and the modelling workflow: the same loop code as ``rigd run`` (supervisor, K∞,
Eq. 1, PD loops, recording) on the compiled plant kernel, deterministic for a given seed.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rigd import __version__
from rigd.data.record import Record
from rigd.driver import data_source
from rigd.frame import RECORD_NAMES
from rigd.rigconfig import LoadedConfig, RigConfig, default_config, load_config


def _effects_overrides(effects) -> dict[str, Any]:
    if effects is None:
        return {}
    if isinstance(effects, dict):
        out = {}
        for name, v in effects.items():
            if isinstance(v, bool):
                out[name] = {"enabled": v}
            else:
                out[name] = {"enabled": True, **dict(v)}
        return out
    return {name: {"enabled": True} for name in effects}


def simulate_record(config=None, excitation=None, *, effects=None, seed: int | None = None,
                    omega_rpm: float | None = None, p_inj_bar: float | None = None,
                    controller=None, controller_on: bool | None = None,
                    settle_s: float = 0.2, pre: int = 0, post: int = 0,
                    events: Sequence = (), kind: str = "sim",
                    meta: dict[str, Any] | None = None) -> Record:
    """Play ``excitation`` on the simulated plant in lock-step; return the recorded frames.

    Parameters
    ----------
    config : path, LoadedConfig, RigConfig or None
        A sim config (default: built-in defaults with the ``sim`` driver).
    excitation : array (n, 2), V
        Added to [r_x, r_y] for n cycles (None: ``n = 0``, only ``pre``/``post``).
    effects : dict or list, optional
        Plant effects to switch on, e.g. ``["delay"]`` or ``{"delay": {"samples": 3}}``
        (overrides ``plant.effects`` of the config).
    seed : int, optional
        Plant noise seed (default: the config's).
    omega_rpm, p_inj_bar : float, optional
        Operating point Ω (rpm), P_I (bar) (default: the config's ``plant``).
    controller : path or rigd.controller.Controller, optional
        K∞ loaded; ``controller_on=True`` enables it (bumpless ramp) at the segment start.
    settle_s : float
        Unrecorded time run first so the plant and PD loops reach equilibrium, s.
    pre, post : int
        Recorded cycles without excitation before and after it.
    events : sequence of (cycle_offset, callable(driver))
        Called with the plant driver just before that cycle (offset from the first excitation
        cycle), e.g. ``(100, lambda plant: plant.impact("x", 50.0, 0.001))``.

    Returns
    -------
    rigd.data.record.Record
        Every channel of :data:`rigd.frame.RECORD_CHANNELS` (``t = seq / fs``), with meta
        ``omega_rpm``, ``p_inj_bar``, ``kind``, ``seed``, ``effects``, ``first_seq``.
    """
    from rigd.loop.app import build_loop

    if config is None:
        lc = default_config()
    elif isinstance(config, LoadedConfig):
        lc = config
    elif isinstance(config, RigConfig):
        lc = LoadedConfig(config, "<memory>", "")
    else:
        lc = load_config(Path(config))
    over: dict[str, Any] = {}
    if seed is not None:
        over["seed"] = int(seed)
    if omega_rpm is not None:
        over["omega_rpm"] = float(omega_rpm)
    if p_inj_bar is not None:
        over["p_inj_bar"] = float(p_inj_bar)
    eff = _effects_overrides(effects)
    if eff:
        over["effects"] = eff
    exc = np.zeros((0, 2)) if excitation is None else np.asarray(excitation, dtype=float)
    loop = build_loop(lc, clock="lockstep", controller=controller, plant_overrides=over)
    plant = loop.fast
    with loop:
        loop.run_for(settle_s)
        res = loop.run_segment(exc, record="memory", controller_on=controller_on, pre=pre,
                               post=post,
                               events=[(off, (lambda f=fn: f(plant))) for off, fn in events])
    frames = res.frames
    cols = {name: frames[:, i].copy() for i, name in enumerate(RECORD_NAMES)}
    info = plant.describe() if hasattr(plant, "describe") else {}
    m: dict[str, Any] = {"omega_rpm": info.get("omega_rpm", omega_rpm or 0.0),
                         "p_inj_bar": info.get("p_inj_bar", p_inj_bar),
                         "kind": kind, "seed": info.get("seed", seed),
                         "effects": info.get("effects_enabled", []),
                         "first_seq": res.first_seq, "faults": res.faults,
                         "rigd_version": __version__,   # made by rigd's loop, as a recording
                         **data_source(plant, loop.slow)}
    m.update(meta or {})
    return Record(cols, lc.config.loop.fs_hz, m, source="<simulate_record>")
