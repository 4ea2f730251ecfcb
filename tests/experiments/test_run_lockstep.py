"""Every experiment kind runs lock-step on the simulated plant; the records match the request."""

import json

import numpy as np
import pytest

from rigd.controller import save_controller
from rigd.data import load_record
from rigd.data.manifest import read_manifest
from rigd.errors import InputError
from rigd.experiments.runner import run_experiment
from rigd.loop.app import build_loop
from rigd.rigconfig import default_config

FS = 5000.0


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    # a small stable K∞(z) (first-order low-pass, gain 0.01 V/µm) so "K∞ on" is real
    ctrl = tmp_path_factory.mktemp("ctrl") / "k.yaml"
    save_controller(ctrl, [[0.9]], [[0.1, 0.0]], [[0.01], [0.0]], [[0.0, 0.0], [0.0, 0.0]],
                    fs_hz=FS)
    lp = build_loop(default_config(), clock="lockstep", controller=ctrl)
    with lp:
        yield lp


def _run(loop, tmp_path, spec, **kw):
    man = run_experiment(spec, loop, tmp_path / "run", **kw)
    data = read_manifest(tmp_path / "run")
    assert data["status"] == man.status
    return man, data


def _check_manifest(data, n_points):
    for key in ("experiment", "started", "finished", "software", "config", "fs_hz", "points",
                "files", "missing", "mode"):
        assert key in data, key
    assert data["software"]["rigd_version"] and data["config"]["sha256"].startswith("sha256:")
    assert data["mode"] == "lockstep" and data["fs_hz"] == FS
    assert len(data["points"]) == n_points


def test_prbs_levels_and_switching(loop, tmp_path):
    spec = {"kind": "prbs", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
            "amplitude_v": [1.0, 0.6], "switch_probability": 0.25, "min_hold_s": 0.001,
            "seed": 5, "duration_s": 1.0, "lead_in_s": 0.1}
    man, data = _run(loop, tmp_path, spec)
    assert man.status == "complete" and data["missing"] == []
    _check_manifest(data, 1)
    f = data["files"][0]
    assert f["kind"] == "prbs" and f["omega_rpm"] == 0 and f["p_inj_bar"] == 4.0
    rec = load_record(tmp_path / "run" / f["path"])
    assert rec.n == f["n_frames"] == int(1.1 * FS)
    assert rec.kind == "prbs" and rec.p_inj_bar == 4.0
    lead = rec.meta["lead_in_samples"]
    assert lead == 500 and not rec.col("x_x")[:lead].any()
    hold = 5
    for ch, amp in (("x_x", 1.0), ("x_y", 0.6)):
        x = rec.col(ch)[lead:]
        assert set(np.unique(x)) == {-amp, amp}
        sw = np.flatnonzero(np.diff(x)) + 1
        assert np.all(sw % hold == 0)               # switches only at bit boundaries
        n_bits = len(x) // hold
        assert abs(len(sw) - 0.25 * n_bits) < 4 * np.sqrt(0.1875 * n_bits)
    # the loop added the excitation to r (K∞ off: r = excitation)
    assert np.array_equal(rec.col("r_x"), rec.col("x_x")) and not rec.col("k_on").any()
    assert np.std(rec.col("e_x")[lead:]) > 10 * np.std(rec.col("e_x")[50:lead]) > 0


@pytest.mark.parametrize("kind,extra", [
    ("multilevel", {"levels": 5, "min_hold_s": 0.002, "duration_s": 0.5}),
    ("multisine", {"f_min_hz": 10, "f_max_hz": 300, "period_s": 0.1, "periods": 3}),
    ("chirp", {"f0_hz": 10, "f1_hz": 400, "duration_s": 0.5}),
])
def test_other_excitations(loop, tmp_path, kind, extra):
    spec = {"kind": kind, "operating_point": {"omega_rpm": 0, "p_inj_bar": 5.0},
            "amplitude_v": 1.0, "lead_in_s": 0.05, "axes": ["x"], **extra}
    man, data = _run(loop, tmp_path, spec)
    assert man.status == "complete"
    rec = load_record(tmp_path / "run" / data["files"][0]["path"])
    x = rec.col("x_x")[250:]
    assert not rec.col("x_y").any() and np.max(np.abs(x)) == pytest.approx(1.0)
    if kind == "multilevel":
        assert np.allclose(np.unique(x), [-1, -0.5, 0, 0.5, 1])
    if kind == "multisine":
        assert len(x) == 1500 and np.allclose(x[:500], x[500:1000])


def test_runout_length_and_speed(loop, tmp_path):
    spec = {"kind": "runout", "operating_point": {"omega_rpm": 6000, "p_inj_bar": 4.0},
            "revolutions": 20}
    man, data = _run(loop, tmp_path, spec)
    rec = load_record(tmp_path / "run" / data["files"][0]["path"])
    assert rec.n == int(20 * 60 / 6000 * FS) and not rec.col("x_x").any()
    assert rec.omega_rpm == 6000 and np.all(rec.col("omega_rpm") == 6000)
    revs = np.count_nonzero(np.diff(rec.col("phi")) < -np.pi)  # wraps of the encoder angle
    assert revs in (19, 20)


def test_impact_windows_controller_off_and_on(loop, tmp_path):
    spec = {"kind": "impact", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
            "axis": "y", "controller": [False, True], "repeats": 2, "pre_s": 0.01,
            "post_s": 0.1, "spacing_s": 0.05, "peak_n": 40.0, "pulse_s": 0.001}
    man, data = _run(loop, tmp_path, spec)
    assert man.status == "complete" and len(data["files"]) == 4
    n_pre = 50
    for f in data["files"]:
        rec = load_record(tmp_path / "run" / f["path"])
        assert rec.n == f["n_frames"] == 50 + 500
        fy = rec.col("f_y")
        assert not rec.col("f_x").any()
        assert not fy[:n_pre].any()                       # nothing before the trigger
        assert n_pre <= np.argmax(fy) <= n_pre + 5         # the hit is at the trigger
        assert 30.0 < fy.max() <= 40.0
        k_on = rec.col("k_on")
        assert np.all(k_on == (1.0 if f["controller_on"] else 0.0))
        assert rec.meta["axis"] == "y" and rec.meta["trigger_index"] == n_pre
    assert [f["controller_on"] for f in data["files"]] == [False, False, True, True]
    assert loop.status()["controller"]["enabled"] is False   # restored


def test_sweep_every_point_present(loop, tmp_path):
    spec = {"kind": "sweep", "grid": {"omega_rpm": [0, 3000], "p_inj_bar": [3.0, 5.0, 7.0]},
            "settle": {"hold_s": 0.02}, "at_each": {"kind": "prbs", "amplitude_v": 1.0,
                                                    "duration_s": 0.1, "lead_in_s": 0.02}}
    man, data = _run(loop, tmp_path, spec)
    _check_manifest(data, 6)
    assert man.status == "complete" and data["missing"] == []
    got = set()
    for pt in data["points"]:
        assert pt["status"] == "done" and pt["settle"]["settled"] and len(pt["files"]) == 1
        rec = load_record(tmp_path / "run" / pt["files"][0])
        assert rec.omega_rpm == pt["omega_rpm"] and rec.p_inj_bar == pt["p_inj_bar"]
        assert np.all(rec.col("omega_rpm") == pt["omega_rpm"])
        assert np.all(rec.col("p_inj_bar") == pt["p_inj_bar"])
        got.add((pt["omega_rpm"], pt["p_inj_bar"]))
    assert got == {(w, p) for w in (0, 3000) for p in (3.0, 5.0, 7.0)}
    assert sorted(x.name for x in (tmp_path / "run").iterdir()) == sorted(
        ["manifest.json"] + [f["path"] for f in data["files"]])


def test_never_overwrites_and_refuses_before_running(loop, tmp_path):
    spec = {"kind": "runout", "operating_point": {"omega_rpm": 3000, "p_inj_bar": 4.0},
            "revolutions": 10}
    _run(loop, tmp_path, spec)
    before = json.loads((tmp_path / "run" / "manifest.json").read_text())
    with pytest.raises(InputError, match="not empty"):
        run_experiment(spec, loop, tmp_path / "run")
    assert json.loads((tmp_path / "run" / "manifest.json").read_text()) == before
    bad = {"kind": "multisine", "amplitude_v": 1, "f_min_hz": 10, "f_max_hz": 2600,
           "period_s": 0.1}
    with pytest.raises(InputError, match="Nyquist"):
        run_experiment(bad, loop, tmp_path / "run2")
    assert not (tmp_path / "run2").exists()


def test_manager_start_status_stop(loop, tmp_path):
    """The daemon's ExperimentHost: runs in an experiment process, stop keeps completed
    points."""
    import time

    from rigd.service.experiment_host import ExperimentHost as ExperimentManager

    mgr = ExperimentManager(loop, runs_root=tmp_path / "runs")
    spec = {"kind": "sweep", "grid": {"omega_rpm": [0, 1000, 2000, 3000],
                                      "p_inj_bar": [3.0, 4.0, 5.0, 6.0]},
            "settle": {"hold_s": 0.02},
            "at_each": {"kind": "prbs", "amplitude_v": 1.0, "duration_s": 0.5,
                        "lead_in_s": 0.02}}
    started = mgr.start(spec=spec)
    assert started["kind"] == "sweep" and started["run_dir"]
    with pytest.raises(InputError, match="already running"):
        mgr.start(spec=spec)
    deadline = time.monotonic() + 60
    while mgr.status().get("done", 0) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert mgr.stop()["stopping"] is True
    mgr.join(60)
    st = mgr.status()
    assert st["state"] == "interrupted" and st["missing"], st
    data = read_manifest(st["run_dir"])
    done = [p for p in data["points"] if p["status"] == "done"]
    assert 2 <= len(done) < 16 and len(done) + len(data["missing"]) == 16
    with pytest.raises(InputError, match="unknown kind"):
        mgr.start(spec={"kind": "bogus"})


@pytest.mark.parametrize("name", ["prbs", "multilevel", "multisine", "chirp", "runout",
                                  "impact", "sweep"])
def test_shipped_examples_validate(name, loop):
    from testpaths import ROOT

    from rigd.experiments.points import check_against_rate
    from rigd.experiments.runner import load

    exp = load(ROOT / "config" / "experiments" / f"{name}.yaml")
    assert exp.spec.kind == name
    check_against_rate(exp.point_spec, FS, exp.source)


def test_shipped_impact_runs(loop, tmp_path):
    from testpaths import ROOT

    man, data = _run(loop, tmp_path, ROOT / "config" / "experiments" / "impact.yaml")
    assert man.status == "complete" and len(data["files"]) == 3


def test_fault_during_a_recording_fails_the_point_and_keeps_the_file(tmp_path):
    # a 300 N hit drives the shaft beyond the allowed fraction of the film gap: the supervisor
    # latches shaft_displacement and the valves go safe. The point must not read as done (it
    # did before: status complete with a record of the safe state), and the file is kept.
    spec = {"kind": "impact", "operating_point": {"omega_rpm": 0, "p_inj_bar": 4.0},
            "axis": "x", "controller": [False], "repeats": 1, "pre_s": 0.01,
            "post_s": 0.05, "spacing_s": 0.0, "peak_n": 300.0, "pulse_s": 0.001}
    with build_loop(default_config(), clock="lockstep") as lp:
        man, data = _run(lp, tmp_path, spec)
        assert any(f["name"] == "shaft_displacement" for f in lp.faults())
    assert man.status == "failed"
    (pt,) = data["points"]
    assert pt["status"] == "failed" and "shaft_displacement" in pt["error"]
    assert len(data["files"]) == 1                       # listed, and readable
    rec = load_record(tmp_path / "run" / data["files"][0]["path"])
    assert rec.n == data["files"][0]["n_frames"] > 0


class _StopInsideTheRename:
    """A stop flag whose request arrives exactly while a finished record is renamed into
    place (the window in which a SIGINT once left a complete file the manifest did not list:
    tests/experiments/test_cli_experiment.py::test_sweep_sigint_keeps_completed_points)."""

    reason = "interrupted by SIGINT"

    def __init__(self, at_entry):
        self.at_entry, self.entries, self._set = at_entry, 0, False

    def is_set(self):
        return self._set

    def deferring(self):
        import contextlib

        @contextlib.contextmanager
        def cm():
            self.entries += 1
            if self.entries == self.at_entry:
                self._set = True          # what _SigintStop._on_sigint does inside the block
            yield
        return cm()


@pytest.mark.parametrize("at_entry", [1, 2])
def test_a_stop_during_the_rename_keeps_the_record_listed_and_its_point_done(loop, tmp_path,
                                                                           at_entry):
    stop = _StopInsideTheRename(at_entry)
    spec = {"kind": "sweep", "grid": {"omega_rpm": [0, 1000], "p_inj_bar": [3.0, 5.0]},
            "settle": {"hold_s": 0.02}, "at_each": {"kind": "prbs", "amplitude_v": 1.0,
                                                    "duration_s": 0.05, "lead_in_s": 0.01}}
    man, data = _run(loop, tmp_path, spec, stop=stop)
    assert man.status == "interrupted"
    done = [p for p in data["points"] if p["status"] == "done"]
    assert [p["index"] for p in done] == list(range(at_entry))   # the renamed one is done
    assert data["missing"] == list(range(at_entry, 4))
    listed = sorted(f["path"] for f in data["files"])
    assert listed == sorted(p["files"][0] for p in done)
    assert sorted(x.name for x in (tmp_path / "run").iterdir()) == ["manifest.json", *listed]
    for p in done:
        assert load_record(tmp_path / "run" / p["files"][0]).n > 0


def test_sigint_inside_deferring_only_sets_the_flag():
    import os
    import signal

    from rigd.cli.experiment import _SigintStop

    with _SigintStop() as stop:
        with stop.deferring():
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):         # the handler runs between bytecodes: give it some
                if stop.is_set():
                    break
        assert stop.is_set()
        stop.clear()
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(10**6):
                pass
        assert stop.is_set()


def test_sigint_inside_a_finaliser_only_sets_the_flag():
    """A KeyboardInterrupt raised inside a weakref callback or ``__del__`` is printed as a
    traceback and dropped by Python (a `rigd experiment` run once printed one): there the
    handler only sets the flag."""
    import types
    import weakref

    from rigd.cli.experiment import _SigintStop

    def frame_of(filename, name):
        code = compile("pass", filename, "exec").replace(co_name=name)
        return types.SimpleNamespace(f_code=code)

    with _SigintStop() as stop:
        for frame in (frame_of(weakref.__file__, "remove"), frame_of("/x/thing.py", "__del__")):
            stop._on_sigint(2, frame)            # no KeyboardInterrupt
            assert stop.is_set()
            stop.clear()
        with pytest.raises(KeyboardInterrupt):
            stop._on_sigint(2, frame_of("/x/runner.py", "run"))
        assert stop.is_set()
