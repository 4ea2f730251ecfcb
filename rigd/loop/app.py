"""Build a :class:`~rigd.loop.loop.ControlLoop` from a config file (drivers by name)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rigd.controller import Controller, gates_from, load_controller
from rigd.errors import InputError
from rigd.loop.loop import ControlLoop
from rigd.rigconfig import LoadedConfig, load_config


def build_drivers(lc: LoadedConfig, *, plant_overrides: dict[str, Any] | None = None):
    """Instantiate the fast driver and the slow drivers of a loaded config.

    ``plant_overrides`` (sim only) update the plant options (e.g. ``seed``, ``effects``).
    """
    cfg = lc.config
    fs = cfg.loop.fs_hz
    cls, opts = lc.driver_options("fast")
    if plant_overrides:
        base = opts.model_dump() if hasattr(opts, "model_dump") else dict(opts)
        base = _merge(base, plant_overrides)
        opts = cls.Options.model_validate(base) if hasattr(cls, "Options") else base
    fast = cls(_as_dict(opts), fs=fs)
    slow, hz = [], []
    for i, spec in enumerate(cfg.drivers.slow):
        scls, sopts = lc.driver_options("slow", i)
        d = scls(_as_dict(sopts), fs=fs)
        d.poll_hz = spec.poll_hz
        slow.append(d)
        hz.append(spec.poll_hz)
    return fast, slow, hz


def _as_dict(opts) -> dict:
    return opts.model_dump() if hasattr(opts, "model_dump") else dict(opts)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


def build_loop(config: str | Path | LoadedConfig, *, clock: str | None = None,
               controller: str | Path | None = None,
               plant_overrides: dict[str, Any] | None = None) -> ControlLoop:
    """A ready (not yet opened) loop for a config file or a loaded config.

    The controller is ``controller`` if given, else the config's ``controller:`` key (a path
    relative to the config file).
    """
    lc = config if isinstance(config, LoadedConfig) else load_config(config)
    fast, slow, hz = build_drivers(lc, plant_overrides=plant_overrides)
    ctrl = controller
    if ctrl is None and lc.config.controller is not None:
        p = Path(lc.config.controller)
        ctrl = p if p.is_absolute() or lc.path.startswith("<") else Path(lc.path).parent / p
    try:
        if ctrl is not None and not isinstance(ctrl, Controller):
            # the start-up controller passes the config's gates, as `rigd ctl load` does
            ctrl = load_controller(ctrl, expected_fs_hz=lc.config.loop.fs_hz,
                                   gates=gates_from(lc.gate_options()))
        return ControlLoop(lc, fast, slow_drivers=slow, slow_poll_hz=hz, controller=ctrl,
                           clock=clock)
    except InputError:
        fast.close()
        raise
