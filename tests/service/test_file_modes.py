"""Files written by rigd get the caller's umask (0644 under umask 022, 0640 under 027), and are
still written atomically: model, controller, report (index.html beside its PNGs) and
recordings (the loop's HDF5 recorder and the atomic HDF5 writer)."""

import os
import stat

import numpy as np
import pytest

UMASKS = [0o022, 0o027]


@pytest.fixture(params=UMASKS, ids=lambda m: f"umask{m:03o}")
def umask(request):
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


def _expect(umask):
    return 0o666 & ~umask


def _no_temp_left(folder):
    left = [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
    assert left == [], left


def test_controller_file(tmp_path, umask):
    from rigd.controller import load_controller, save_controller

    path = tmp_path / "k.yaml"
    save_controller(path, [[0.5]], [[0.1, 0.0]], [[1.0], [0.0]], np.zeros((2, 2)), fs_hz=5000.0)
    assert _mode(path) == _expect(umask)
    assert load_controller(path) is not None
    _no_temp_left(tmp_path)


def test_model_file(tmp_path, umask):
    from rigd.ident.greybox.rotor import actuator_structure
    from rigd.ident.modelfile import ModelFile, Submodel, load_model

    ast = actuator_structure()
    theta = ast.pack(np.diag([4e6] * 4), np.diag([4e3] * 4), np.diag([4e6] * 4))
    mf = ModelFile(5000.0, {"actuator": Submodel("actuator", ast, theta, np.zeros_like(theta))})
    path = tmp_path / "model.yaml"
    mf.save(path)
    assert _mode(path) == _expect(umask)
    assert set(load_model(path).submodels) == {"actuator"}
    _no_temp_left(tmp_path)


def test_report_page_and_figures(tmp_path, umask):
    from rigd.htmlreport import Report

    rep = Report(tmp_path / "rep", "modes")
    fig, ax = rep.figure("curve", "a line")
    ax.plot([0, 1], [1, 0])
    page = rep.write()
    assert _mode(page) == _expect(umask)
    assert _mode(rep.figures[0]) == _expect(umask)   # index.html like its PNGs
    _no_temp_left(tmp_path / "rep")


def test_recordings(tmp_path, umask):
    from rigd.data.h5io import write_h5
    from rigd.data.io import load_record
    from rigd.loop.loop import ControlLoop
    from rigd.loop.sinks import RecordSpec
    from rigd.rigconfig import default_config
    from rigd_drivers.sim.driver import SimPlantDriver

    loop = ControlLoop(default_config(clock={"mode": "lockstep"}),
                       SimPlantDriver({"seed": 1}, fs=5000.0))
    rec = tmp_path / "loop.h5"
    with loop:
        loop.run_segment(np.zeros((500, 2)), record=RecordSpec(str(rec)))
    assert _mode(rec) == _expect(umask)
    record = load_record(rec)
    assert record.n == 500
    copy = tmp_path / "copy.h5"
    write_h5(copy, record)                 # the atomic writer (CSV import, tests, benches)
    assert _mode(copy) == _expect(umask)
    assert load_record(copy).n == 500
    _no_temp_left(tmp_path)


def test_failed_atomic_write_leaves_nothing(tmp_path, umask):
    from rigd.fileio import atomic_open, atomic_write_text

    path = tmp_path / "x.txt"
    atomic_write_text(path, "old")
    with pytest.raises(RuntimeError), atomic_open(path) as fh:
        fh.write("half")
        raise RuntimeError("interrupted")
    assert path.read_text() == "old" and _mode(path) == _expect(umask)
    _no_temp_left(tmp_path)
