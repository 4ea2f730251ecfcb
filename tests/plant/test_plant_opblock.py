"""The compiled operating-point block (rigd_drivers.sim.opblock) against an independent build.

An operating-point change used to assemble the block in Python around the matrix exponentials
(~150 µs of GIL per change: the loop thread overran waiting for it, bench figure
``op_change_miss_fraction``); now it is one compiled call without the GIL. The reference here
is built the readable way: ``bearing_augmented`` + :func:`rigd.lti.foh` with
``scipy.linalg.expm`` and LAPACK's balancing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigd import lti
from rigd_drivers.plant import physics as phys
from rigd_drivers.sim import kernel as k
from rigd_drivers.sim.driver import SimPlantDriver
from rigd_drivers.sim.options import PlantOptions
from rigd_drivers.sim.params import ParamBlocks, bearing_augmented

ALL_ON = {"effects": {name: {"enabled": True} for name in
                      ("extra_mode", "cubic_stiffness", "runout", "creep", "hysteresis",
                       "delay")}}
POINTS = [(0.0, 3.0), (1234.5, 4.4), (3000.0, 5.0), (6000.0, 7.0)]


def _reference_op_part(opts: PlantOptions, om: float, pi: float, fs: float) -> dict:
    T = 1.0 / fs
    A, B, _ = bearing_augmented(opts, om, pi)
    out = {}
    for (lo_phi, lo_g0, lo_g1), dt in (((k.A_PHI, k.A_G0, k.A_G1), T),
                                       ((k.A_SPHI, k.A_SG0, k.A_SG1), T / opts.substeps)):
        Phi, G0, G1 = lti.foh(A, B, dt)          # scipy expm, LAPACK balancing
        out[lo_phi] = Phi.ravel()
        out[lo_g0] = G0.ravel()
        out[lo_g1] = G1.ravel()
    w = om * 2 * math.pi / 60
    ef = opts.effects
    bm = phys.bearing_matrices(om, pi)
    k3 = (ef.cubic_stiffness.ratio_at_gap * 1e-6 * float(np.mean(np.diag(bm.K)))
          / phys.GAP_UM ** 2) if ef.cubic_stiffness.enabled else 0.0
    unb = ef.runout.unbalance_g_mm * 1e-6 * w ** 2 if ef.runout.enabled else 0.0
    out.update({k.A_K3: np.array([k3]), k.A_UNB: np.array([unb]),
                k.A_OMEGA_RAD: np.array([w]), k.A_OMEGA_RPM: np.array([om]),
                k.A_PINJ: np.array([pi])})
    return out


@pytest.mark.parametrize("options", [{}, ALL_ON], ids=["plain", "all-effects"])
def test_compiled_block_matches_the_readable_build(options):
    opts = PlantOptions.model_validate(options)
    blocks = ParamBlocks(opts, 5000.0)
    seen = np.zeros(k.NA, bool)
    for om, pi in POINTS:
        b = blocks(om, pi)
        for lo, ref in _reference_op_part(opts, om, pi, 5000.0).items():
            got = b[lo:lo + len(ref)]
            scale = max(np.abs(ref).max(), 1e-300)
            assert np.abs(got - ref).max() <= 1e-12 * scale, (om, pi, lo)
            seen[lo:lo + len(ref)] = True
        # everything else is the operating-point-independent template
        assert np.array_equal(b[~seen], blocks.template[~seen])
    assert blocks.template[k.A_NX] == (6 if options else 4)


def test_driver_change_reaches_the_active_block():
    plant = SimPlantDriver({"seed": 3, **ALL_ON}, fs=5000.0)
    plant.prepare_operating_point(4500.0, 6.5)()
    plant.write(np.zeros(4))                     # the kernel swaps the staged block in
    active = plant.params[k.ACT:k.ACT + k.NA]
    ref = _reference_op_part(plant.opts, 4500.0, 6.5, 5000.0)
    assert np.allclose(active[k.A_PHI:k.A_PHI + k.NX * k.NX], ref[k.A_PHI], rtol=0,
                       atol=1e-12 * np.abs(ref[k.A_PHI]).max())
    assert active[k.A_OMEGA_RPM] == 4500.0 and active[k.A_PINJ] == 6.5
    assert plant.operating_point == (4500.0, 6.5)
