"""``trigger: operator`` impacts on the real-time loop: the operator (a thread here, as a hand
on the hammer) hits during the wait; the window around the hit is cut from the wait recording
and written by a spawned helper process (``rigd.experiments.window``), never in the loop's
process. No hit: the point fails with one line, which came back from the helper."""

import threading

import numpy as np
import pytest

from rigd.data import load_record
from rigd.data.manifest import read_manifest
from rigd.experiments.runner import run_experiment
from rigd.loop.app import build_loop
from rigd.rigconfig import default_config

PROCESS_S = 600.0          # hang bound only
SPEC = {"kind": "impact", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0}, "axis": "x",
        "controller": [False], "repeats": 1, "pre_s": 0.01, "post_s": 0.1, "spacing_s": 0.0,
        "trigger": "operator", "trigger_n": 5.0, "timeout_s": 2.0}


@pytest.fixture(scope="module")
def loop():
    cfg = default_config(clock={"spin_us": 0.0}, supervisor={"overrun_storm_count": 10**9})
    lp = build_loop(cfg, clock="realtime")
    with lp:
        lp.start()
        yield lp


def _operator(loop, stop):
    """Hit once the wait recording has played 0.5 s (a condition on the playing segment)."""
    while not stop.is_set():
        seg = loop.player.current
        sink = getattr(seg, "sink", None)
        path = str(getattr(sink, "path", ""))
        if path.endswith(".wait.part") and seg.i > 2500:
            loop.fast.impact("x", 40.0, 0.001)
            return
        stop.wait(0.005)


def test_operator_hit_window_cut_by_a_helper_process(loop, tmp_path):
    stop = threading.Event()
    hand = threading.Thread(target=_operator, args=(loop, stop), daemon=True)
    hand.start()
    try:
        man = run_experiment(SPEC, loop, tmp_path / "run")
    finally:
        stop.set()
        hand.join(PROCESS_S)
    data = read_manifest(tmp_path / "run")
    assert man.status == "complete" and data["missing"] == [], data
    (f,) = data["files"]
    rec = load_record(tmp_path / "run" / f["path"])
    n_pre = 50
    assert rec.n == f["n_frames"] == n_pre + 500 and f["trigger_index"] == n_pre
    fx = rec.col("f_x")
    assert int(np.flatnonzero(np.abs(fx) >= 5.0)[0]) == n_pre      # the window is on the hit
    assert 30.0 < fx.max() <= 40.0 and rec.meta["axis"] == "x"
    assert not list((tmp_path / "run").rglob("*.wait*"))            # the wait is gone


def test_no_operator_hit_fails_the_point_in_one_line(loop, tmp_path):
    man = run_experiment({**SPEC, "timeout_s": 0.5}, loop, tmp_path / "run")
    data = read_manifest(tmp_path / "run")
    assert man.status != "complete", data
    text = str(data)
    assert "no hammer hit above 5 N on f_x within 0.5 s" in text, text
    # the wait is measured data: kept, listed as such (never deleted)
    (f,) = data["files"]
    assert f["kind"] == "impact_wait" and f["path"].endswith("_wait.h5"), f
    assert load_record(tmp_path / "run" / f["path"]).n == f["n_frames"] == 2500
    assert not list((tmp_path / "run").rglob("*.part"))
