"""`rigd diagnose --json` on rotor data this project did not make.

The interchange CSVs here come from scipy alone (no rigd simulator, no rigd writer): valves
as second-order lags driven by held references r (a DAC), a cross-coupled 2-DOF bearing driven
by the valve positions u, optionally an unmodelled structural mode at 430 Hz, all discretised
exactly for the held r (``cont2discrete``, ZOH), then written with plain ``print``-style
formatting. The record carries no ``rigd_version`` and no ``intersample`` key, so the inputs'
hold is chosen from the data.
"""

import json

import numpy as np
import pytest
from scipy import signal

from rigd.cli import main

FS = 5000.0
N = 12000


def _write(path, extra_mode: bool, seed: int = 1) -> None:
    rng = np.random.default_rng(seed)
    r = np.empty((N, 2))
    for j in range(2):
        k = 0
        while k < N:
            h = int(rng.integers(3, 20))
            r[k:k + h, j] = rng.choice(np.linspace(-1, 1, 7))
            k += h
    wa, za = 2 * np.pi * 550, 0.75
    w, z = 2 * np.pi * np.array([125.0, 150.0]), 0.05
    K = np.diag(w ** 2) + np.array([[0, 0.1], [0.05, 0]]) * w[0] ** 2
    D = np.diag(2 * z * w)
    B = np.diag(w ** 2 * 1.5) + np.array([[0, 0.1], [-0.1, 0]]) * w[0] ** 2
    wm, zm = 2 * np.pi * 430, 0.02
    # states: valve x (u, u'), valve y (u, u'), bearing (p, p'), extra mode (q, q')
    A = np.zeros((12, 12))
    Bc = np.zeros((12, 2))
    for i in range(2):
        A[2 * i, 2 * i + 1] = 1
        A[2 * i + 1, 2 * i] = -wa ** 2
        A[2 * i + 1, 2 * i + 1] = -2 * za * wa
        Bc[2 * i + 1, i] = 2 * wa ** 2
    A[4:6, 6:8] = np.eye(2)
    A[6:8, 4:6] = -K
    A[6:8, 6:8] = -D
    A[6:8, [0, 2]] = B
    A[8:10, 10:12] = np.eye(2)
    A[10:12, 8:10] = -wm ** 2 * np.eye(2)
    A[10:12, 10:12] = -2 * zm * wm * np.eye(2)
    A[10:12, [0, 2]] = 0.3 * wm ** 2 * np.eye(2)
    C = np.zeros((4, 12))
    C[0, 0] = C[1, 2] = C[2, 4] = C[3, 5] = 1
    if extra_mode:
        C[2, 8] = C[3, 9] = 1
    Ad, Bd, *_ = signal.cont2discrete((A, Bc, C, np.zeros((4, 2))), 1 / FS, "zoh")
    x = np.zeros(12)
    Y = np.empty((N, 4))
    for k in range(N):
        Y[k] = C @ x
        x = Ad @ x + Bd @ r[k]
    Y[:, :2] += 0.002 * rng.standard_normal((N, 2))
    Y[:, 2:] += 0.005 * rng.standard_normal((N, 2))
    with open(path, "w") as fh:
        fh.write("# rig-data: 1\n# fs: 5000\n# omega_rpm: 0\n# p_inj_bar: 4.0\n# kind: prbs\n")
        fh.write("t,r_x,r_y,u_x,u_y,e_x,e_y\n")
        for k in range(N):
            fh.write(f"{k / FS:.5f},{r[k, 0]:.6g},{r[k, 1]:.6g},"
                     + ",".join(f"{v:.6g}" for v in Y[k]) + "\n")


@pytest.mark.parametrize("extra_mode", [False, True])
def test_foreign_rotor_csv(tmp_path, capsys, extra_mode):
    path = tmp_path / "rotor.csv"
    _write(path, extra_mode)
    assert main(["diagnose", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["fit_percent"]) == {"actuator", "bearing"}
    assert out["fit_percent"]["actuator"] >= 99.0
    significant = [(f["submodel"], f["effect"]) for f in out["findings"] if f["significant"]]
    if not extra_mode:
        assert significant == [] and out["fit_percent"]["bearing"] >= 99.0
    else:
        top = out["findings"][0]
        assert (top["submodel"], top["effect"]) == ("bearing", "extra_mode")
        assert significant == [("bearing", "extra_mode")]
        err0 = 100 - out["fit_percent"]["bearing"]
        assert err0 >= 3 * (100 - top["fit_percent_with"]), (err0, top["fit_percent_with"])
