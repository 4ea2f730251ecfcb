"""Configuration: the shipped files validate; bad ones are refused with file:line: key: problem."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rigd.cli import main
from rigd.rigconfig import load_config

ROOT = Path(__file__).resolve().parents[2]
SIM = (ROOT / "config" / "sim.yaml").read_text()


@pytest.mark.parametrize("name", ["sim.yaml", "rig.yaml"])
def test_shipped_configs_validate(name):
    lc = load_config(ROOT / "config" / name)
    assert lc.config.loop.fs_hz == 5000.0 and lc.config.loop.r0_v == 5.0
    assert len(lc.config.valves) == 4


def test_rig_config_drivers_and_calibration():
    lc = load_config(ROOT / "config" / "rig.yaml")
    cls, opts = lc.driver_options("fast")
    assert cls.name == "serial" and opts.port.startswith("/dev/")
    scls, sopts = lc.driver_options("slow", 0)
    assert scls.name == "modbus" and sopts.host == "192.168.10.20"
    g, o = lc.config.calibration_arrays()
    assert g[0] == 0.987 and o[0] == -3.2 and g[2] == 1.0


def _line_of(text: str, needle: str) -> int:
    for i, line in enumerate(text.splitlines(), 1):
        if needle in line:
            return i
    raise AssertionError(needle)


# (description, text transformation, key path, expected line marker, problem pattern)
BAD = [
    ("unknown key", lambda t: t.replace("  r0_v: 5.0", "  r0_volts: 5.0"),
     "loop.r0_volts", "r0_volts", "unknown key"),
    ("wrong type", lambda t: t.replace("fs_hz: 5000.0", "fs_hz: fast"),
     "loop.fs_hz", "fs_hz: fast", "valid number"),
    ("out of range", lambda t: t.replace("fs_hz: 5000.0", "fs_hz: -5"),
     "loop.fs_hz", "fs_hz: -5", "greater than 0"),
    ("r0 outside the drive range", lambda t: t.replace("r0_v: 5.0", "r0_v: 12.0"),
     "loop", "loop:", "outside drive_v"),
    ("three valves",
     lambda t: t.replace("  - {kp: 1.5, kd: 1.0e-4, tf_s: 1.0e-4, kff: 1.0}\n", "", 1),
     "valves", "valves:", "exactly 4 valves"),
    ("negative gain", lambda t: t.replace("- {kp: 1.5,", "- {kp: -1.5,", 1),
     "valves[0].kp", "kp: -1.5", "greater than or equal to 0"),
    ("unknown driver", lambda t: t.replace("fast: {name: sim}", "fast: {name: daqmx}"),
     "drivers.fast.name", "daqmx", "unknown driver 'daqmx'"),
    ("plant option out of range", lambda t: t.replace("p_inj_bar: 4.0", "p_inj_bar: 9.0"),
     "plant.p_inj_bar", "p_inj_bar: 9.0", "less than or equal to 7"),
    ("bad clock mode", lambda t: t.replace("mode: realtime", "mode: fastest"),
     "clock.mode", "mode: fastest", "realtime"),
    ("bad overrun policy", lambda t: t.replace("overrun: skip", "overrun: ignore"),
     "clock.overrun", "overrun: ignore", "catch_up"),
]


@pytest.mark.parametrize("desc,edit,key,marker,problem", BAD, ids=[b[0] for b in BAD])
def test_bad_config_refused_with_one_precise_line(tmp_path, capsys, desc, edit, key, marker,
                                                  problem):
    text = edit(SIM)
    assert text != SIM
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    rc = main(["run", "--config", str(path), "--duration", "0"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1, err
    line = _line_of(text, marker)
    assert re.search(rf"{re.escape(str(path))}:{line}: {re.escape(key)}: ", err), err
    assert problem in err, err


def test_bad_yaml_syntax_and_missing_file(tmp_path, capsys):
    path = tmp_path / "broken.yaml"
    path.write_text("loop:\n  fs_hz: [5000\n")
    assert main(["run", "--config", str(path), "--duration", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert "not valid YAML" in err and f"{path}:" in err and len(err.splitlines()) == 1
    assert main(["run", "--config", str(tmp_path / "nope.yaml"), "--duration", "0"]) == 2
    assert "no such file" in capsys.readouterr().err


def test_controller_with_wrong_rate_refused(tmp_path, capsys):
    from rigd.controller import save_controller

    ctrl = tmp_path / "k.yaml"
    save_controller(ctrl, [[0.5]], [[1.0, 0.0]], [[1.0], [0.0]], [[0.0, 0.0], [0.0, 0.0]],
                    fs_hz=1000.0)
    rc = main(["run", "--config", str(ROOT / "config" / "sim.yaml"), "--controller", str(ctrl),
               "--duration", "0"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "differs from the loop rate" in err and str(ctrl) in err
