"""The mechanical n-DOF base's own order search (rigd.ident.greybox.order.choose_order) on a record
with more inputs than outputs: each parallel mode is one mode, whatever the number of inputs
(issue 20: "with two or more inputs no mode can ever be added"). Records from tests/gen
(scipy/numpy only, never rigd's own models)."""

from __future__ import annotations

import numpy as np
import pytest

from rigd.ident.greybox.mechanical import generic_structure
from rigd.ident.greybox.order import choose_order
from rigd.ident.greybox.parallel import ParallelModes
from rigd.ident.iddata import IdData
from tests.gen.linear import THREE_MODES, structure_2in_3modes


def test_two_shakers_one_sensor_three_modes_on_the_mechanical_base():
    g = structure_2in_3modes(seed=11, n=4000)
    d = IdData(g.u, g.y, g.fs, list(g.inputs), list(g.outputs))
    k = int(round(2 * d.n / 3))
    base = generic_structure(d.input_names, d.output_names, hold="zoh")
    c = choose_order(base, d, slice(0, k), slice(k, d.n))
    assert c.modes == 3, c.describe()
    # each mode once in the read-outs and in the poles of the linear part
    got = sorted(m["f_n_hz"] for m in c.structure.modes(c.theta) if "f_n_hz" in m)
    assert got == pytest.approx([f for f, _ in THREE_MODES], rel=0.03)
    assert c.structure.linear_part(c.theta).A.shape == (6, 6)


@pytest.mark.parametrize("nu, ny", [(2, 1), (1, 3), (3, 2)])
def test_parallel_modes_realised_minimally_with_the_simulated_response(nu, ny):
    rng = np.random.default_rng(nu * 10 + ny)
    pm = ParallelModes(2, [f"u{j}" for j in range(nu)], [f"y{i}" for i in range(ny)])
    th = []
    for f, z in ((3.0, 0.05), (7.0, 0.1)):
        th += [f, z] + list(rng.normal(size=nu * ny)) + [0.0] * (2 * ny)
    th = np.asarray(th)
    As, Bs, Cs = pm.blocks(th)
    assert len(As) == 2 * min(nu, ny)   # a pole pair per rank of each mode's gains
    # the realisation's impulse response equals the simulated one (per-input drive)
    from scipy.linalg import block_diag
    from scipy.signal import cont2discrete

    fs, n = 100.0, 400
    A, B, C = block_diag(*As), np.vstack(Bs), np.hstack(Cs)
    Ad, Bd, *_ = cont2discrete((A, B, C, np.zeros((ny, nu))), 1 / fs, "zoh")
    for j in range(nu):
        u = np.zeros((n, nu))
        u[0, j] = 1.0
        x, y_ss = np.zeros(A.shape[0]), np.zeros((n, ny))
        for t in range(n):
            y_ss[t] = C @ x
            x = Ad @ x + Bd @ u[t]
        y_sim = pm.output(th, u, fs, "zoh")
        assert np.max(np.abs(y_sim - y_ss)) <= 1e-9 * max(1.0, np.max(np.abs(y_ss)))
