"""``rigd run --json`` and ``rigd demo`` print strict JSON: a non-finite figure is ``null``
(through ``rigd.cli._args.print_json``, the one NaN policy of every ``--json`` output)."""

from __future__ import annotations

import json
import math

from rigd.cli import main


def _strict(text: str):
    def no_constant(name):
        raise AssertionError(f"non-strict JSON constant {name} in the output")

    return json.loads(text, parse_constant=no_constant)


def test_run_json_writes_a_nan_figure_as_null(capsys, monkeypatch):
    from rigd.loop.loop import ControlLoop

    real = ControlLoop.timing

    def timing(self):
        t = real(self)
        t["realtime_factor"] = math.nan          # a figure that is not a number
        t["wall_s"] = math.inf
        return t

    monkeypatch.setattr(ControlLoop, "timing", timing)
    monkeypatch.delenv("RIGD_SOCKET", raising=False)
    assert main(["run", "--config", "config/sim.yaml", "--lockstep", "--duration", "0.02",
                 "--no-notify", "--json", "--log-level", "error"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["timing"]["cycles"] == 100 and out["faults"] == []
    assert out["timing"]["realtime_factor"] is None and out["timing"]["wall_s"] is None


def test_demo_prints_a_nan_figure_as_null(capsys, monkeypatch, tmp_path):
    import numpy as np

    import rigd.api.demo as demo

    keys = ("sensitivity_reduction_min", "sensitivity_reduction_at_resonance_min",
            "sensitivity_lowfreq_max", "sensitivity_peak_max", "damping_ratio_open",
            "damping_ratio_closed", "damping_increase", "gamma", "controller_order",
            "fit_percent", "run_time_s")
    summary = {k: np.float64(1.5) for k in keys}
    summary["gamma"] = np.float64(np.nan)
    summary["fit_percent"] = {"actuator": -math.inf, "bearing": 91.0}
    summary["diagnosis"] = {"named": ["delay"], "named_by_submodel": {"bearing": ["delay"]},
                            "fit_before": {"bearing": math.nan}, "fit_after": {"bearing": 92.0}}
    seen = {}

    def run_demo(out, **kw):
        seen["out"] = out
        return summary

    monkeypatch.setattr(demo, "run_demo", run_demo)
    assert main(["demo", "--out", str(tmp_path / "d")]) == 0
    text = capsys.readouterr().out
    out = _strict(text)
    assert seen["out"] == str(tmp_path / "d")
    assert out["gamma"] is None and out["damping_increase"] == 1.5
    assert out["fit_percent"] == {"actuator": None, "bearing": 91.0}
    assert out["diagnosis"]["fit_before"] == {"bearing": None}
    assert out["diagnosis"]["named"] == ["delay"]
    assert text.startswith("{\n  \"")                # still indented for a reader
