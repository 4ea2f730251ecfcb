"""The controller's closed-loop check (rigd.controller) without python-control: the same
poles as python-control's ``feedback(G*K, I)``, a continuous plant held and a plant at
another rate re-sampled as python-control's ``c2d`` would, and no import of python-control
in a process that loads a controller through the rig config's gates (the daemon's socket
process does so at its start)."""

import subprocess
import sys

import control
import numpy as np
import pytest
from testpaths import ROOT

from rigd.controller import (
    PlantSS,
    _closed_loop_radius,
    _plant_at,
    closed_loop_check,
    plant_ss,
)
from rigd.errors import InputError

DT = 2e-4


def _random_loop(rng):
    ng, nk = int(rng.integers(1, 6)), int(rng.integers(0, 5))
    g = control.drss(ng, 2, 2)
    G = control.ss(g.A, g.B, g.C, 0.5 * rng.standard_normal((2, 2)), DT)
    Ak = 0.4 * rng.standard_normal((nk, nk))
    Bk, Ck = rng.standard_normal((nk, 2)), rng.standard_normal((2, nk))
    Dk = 0.5 * rng.standard_normal((2, 2))
    return G, Ak, Bk, Ck, Dk


def test_closed_loop_poles_are_python_controls():
    rng = np.random.default_rng(3)
    radii = []
    for _ in range(200):
        G, Ak, Bk, Ck, Dk = _random_loop(rng)
        K = control.ss(Ak, Bk, Ck, Dk, DT) if Ak.size else control.ss(
            np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), Dk, DT)
        p = control.feedback(G * K, np.eye(2), sign=-1).poles()
        ref = float(np.max(np.abs(p)))
        got = _closed_loop_radius(_plant_at(G, DT, "t"), Ak, Bk, Ck, Dk, "t")
        assert got == pytest.approx(ref, rel=1e-9, abs=1e-12)
        radii.append(ref)
    # both verdicts occur among the cases: the comparison covers stable and unstable loops
    assert min(radii) < 1.0 < max(radii)


def test_check_refuses_the_unstable_loop_and_passes_the_stable_one():
    G = PlantSS(np.array([[0.9]]), np.array([[1.0, 0.0]]), np.array([[1.0], [0.0]]),
                np.zeros((2, 2)), DT)
    A, B, C = np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0))
    closed_loop_check(A, B, C, np.diag([0.5, 0.0]), fs_hz=1 / DT, where="k.yaml", plant=G)
    # pole 0.9 - k: k = 2.5 puts it at -1.6
    with pytest.raises(InputError, match=r"unstable on the given plant.*1\.600000"):
        closed_loop_check(A, B, C, np.diag([2.5, 0.0]), fs_hz=1 / DT, where="k.yaml",
                          plant=G)


def test_a_continuous_plant_is_held_and_another_rate_resampled_as_python_control():
    Gc = control.ss([[0, 1], [-4e6, -200]], [[0, 0], [1, 2]], np.eye(2), np.zeros((2, 2)))
    ref = control.c2d(Gc, DT, "zoh")
    for plant in (Gc, control.c2d(Gc, DT / 2, "zoh"), control.c2d(Gc, 3 * DT, "zoh")):
        got = _plant_at(plant, DT, "t")
        np.testing.assert_allclose(got.A, ref.A, atol=1e-9)
        np.testing.assert_allclose(got.B, ref.B, atol=1e-12)
        assert got.dt == DT


def test_a_plant_with_no_continuous_equivalent_is_refused_by_name():
    G = PlantSS(np.array([[-0.5]]), np.array([[1.0, 0.0]]), np.array([[1.0], [0.0]]),
                np.zeros((2, 2)), DT / 2)
    with pytest.raises(InputError, match="no continuous equivalent") as e:
        _plant_at(G, DT, "plant.yaml")
    assert "plant.yaml" in str(e.value)


def test_matrices_that_make_no_state_space_are_named():
    with pytest.raises(InputError, match=r"design_plant: not a valid state space: A 2x2, "
                                         r"B 3x2"):
        plant_ss((np.eye(2), np.ones((3, 2)), np.ones((2, 2)), np.zeros((2, 2))), DT,
                 "c.yaml", what="design_plant")


def test_loading_a_controller_through_the_gates_imports_no_python_control(truth_design):
    """What the socket process does at its start (rigd.service.reader.gates_for): the
    config's nominal plant read and a controller checked against it, without python-control
    (its import, with scipy.signal and matplotlib, cost each daemon start ≈ 1.5 CPU-s)."""
    code = (
        "import sys\n"
        "from rigd.controller import gates_from, load_controller\n"
        "from rigd.rigconfig import load_config\n"
        "lc = load_config('config/sim.yaml')\n"
        "g = gates_from(lc.gate_options())\n"
        "assert g is not None and g.nominal is not None\n"
        f"load_controller({str(truth_design / 'controller.yaml')!r}, expected_fs_hz=5000.0,"
        " gates=g)\n"
        "print(sorted(m for m in ('control', 'matplotlib', 'scipy.signal') "
        "if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=str(ROOT))
    assert out.stdout.strip() == "[]", out
