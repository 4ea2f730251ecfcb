"""Words of the record's domain (issue 20, item 6): on thermal and process records made
outside rigd's model classes (tests/gen: a first-order heater with a transport delay; a
2-input process of two lags), no output of identify, compare or diagnose — text, --json,
report HTML — speaks of stiffness, resonances, a rotor, a bearing or a rotor experiment
file; a 2-input record is never "a single axis". (Rotor records keep their rotor words and
rotor advice: tests/diagnose/test_explanations.py and the rotor tests.)"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from rigd.cli import main
from rigd.htmlpage import plotly_js
from tests.gen import linear
from tests.gen.record import Generated, add_noise
from tests.gen.signals import held_steps

ROOT = Path(__file__).resolve().parents[2]
YAMLS = sorted(p.name for p in (ROOT / "config" / "experiments").glob("*.yaml"))
BANNED = re.compile("|".join(["stiffness", "resonan", "rotor", "bearing", "config/experiments",
                              *map(re.escape, YAMLS)]), re.IGNORECASE)


def process_2in(seed: int = 3, n: int = 1500, fs: float = 0.5) -> Generated:
    """Two inputs (a valve and a heater, %) → one temperature: two lags (20 s, 80 s), the
    heater's path 4 samples late."""
    rng = np.random.default_rng(seed)
    u = np.column_stack([held_steps(n, rng, (10, 40), amp=30.0),
                         held_steps(n, rng, (15, 60), amp=40.0)])
    A = [[-1 / 20.0, 0.0], [0.0, -1 / 80.0]]
    B = [[0.8 / 20.0, 0.0], [0.0, -0.5 / 80.0]]
    clean = 50.0 + linear.simulate_ct(A, B, [[1.0, 1.0]], [[0.0, 0.0]], u, fs, [0.0, 4.0])
    return Generated(u, add_noise(clean, 35.0, rng), fs, ["valve", "heater"], ["temp"],
                     {"valve": "%", "heater": "%", "temp": "degC"}, {"kind": "process"},
                     clean)


RECORDS = {"heater_d3": lambda: linear.thermal(delay=3.0, tau_s=15.0, fs=2.0, n=1500,
                                               seed=1),
           "process_2in": process_2in}


def _run(argv, capsys) -> str:
    assert main(argv) == 0, argv
    out = capsys.readouterr()
    return out.out + out.err


def _html(d: Path) -> str:
    lib = plotly_js()  # the embedded plotting library is not rigd's output
    return "".join(p.read_text().replace(lib, "").replace(lib.replace("</script", "<\\/script"),
                                                          "")
                   for p in sorted(d.glob("*.html")))


@pytest.fixture()
def computed_once(monkeypatch):
    """``rigd.api.identify`` and ``rigd.api.diagnose`` computed once per record and options:
    the text run and the ``--json`` run of one command print the same result (the CLI's
    whole path runs both times, argument parsing and printing included), so the second run
    reuses it rather than fitting again. Where the files go (``out``, ``report``) is not
    part of the key: the first run writes them."""
    from rigd import api

    def once(fit):
        done: dict = {}

        def fit_once(*args, **kw):
            key = repr((args, sorted((k, v) for k, v in kw.items()
                                     if k not in ("out", "report"))))
            if key not in done:
                done[key] = fit(*args, **kw)
            return done[key]
        return fit_once

    for name in ("identify", "diagnose"):
        monkeypatch.setattr(api, name, once(getattr(api, name)))


@pytest.mark.timeout(2400)  # identify and diagnose once each, compare twice, reports included
@pytest.mark.parametrize("name", sorted(RECORDS))
def test_no_mechanical_word_on_a_process_record(name, tmp_path, capsys, computed_once):
    g = RECORDS[name]()
    path = g.write_csv(tmp_path / f"{name}.csv")
    opts = [*g.cli_args(), "--fs", repr(g.fs)]
    model = tmp_path / "m.yaml"
    outs = {
        "identify": _run(["identify", str(path), *opts, "-o", str(model)], capsys),
        "identify --json": _run(["identify", str(path), *opts, "--json"], capsys),
        "compare": _run(["compare", str(model), str(path), *opts, "--part", "validation",
                         "--report", str(tmp_path / "cmp")], capsys),
        "compare --json": _run(["compare", str(model), str(path), *opts, "--part",
                                "validation", "--json"], capsys),
        "diagnose": _run(["diagnose", str(path), *opts, "--report", str(tmp_path / "dg")],
                         capsys),
    }
    djson = _run(["diagnose", str(path), *opts, "--json"], capsys)
    outs["diagnose --json"] = djson
    outs["compare report"] = _html(tmp_path / "cmp")
    outs["diagnose report"] = _html(tmp_path / "dg")
    for what, text in outs.items():
        text = text.replace(str(tmp_path), "<tmp>")  # the test's own directory name
        hits = sorted({m.group(0) for m in BANNED.finditer(text)})
        assert not hits, (what, hits, [text[max(0, m.start() - 120):m.end() + 60]
                                       for m in BANNED.finditer(text)][:3])
        assert "single axis" not in text, what
    d = json.loads(djson)
    assert d["domain"]["generic"]["domain"] == "process", d["domain"]
    assert "yardstick" in d and "yardstick" in json.loads(outs["compare --json"])
