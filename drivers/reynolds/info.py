"""``python -m rigd_drivers.reynolds.info``: the physics-grade plant's figures as JSON.

Prints the checks of docs/plant.md ("The physics-grade plant"): grid convergence, the Ausman
comparison, stiffness and modes against P_I and Ω, the film mass balance and the kernel's CPU
time per step (≈ 30 s).
"""

from __future__ import annotations

import json
import math
import sys
import time

import numpy as np

from rigd.frame import N_IN
from rigd_drivers.reynolds import analysis as an
from rigd_drivers.reynolds import kernel as k
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds import linear

C = 25e-6


def _arrays(**opts):
    return an.make_arrays({"noise": {"e_um": 0.0, "y_p_v": 0.0}, **opts})


def grid_convergence() -> dict:
    out = {}
    for nt, nz in ((32, 8), (64, 16), (128, 32)):
        pa = _arrays(grid={"n_theta": nt, "n_z": nz})
        af = an.valve_area_fractions(pa.opts, 5.0)
        _, fx0, fy0 = an.steady(pa, 0.0, 0.0, af)
        _, fx, fy = an.steady(pa, 0.3 * C, 0.0, af)
        K = an.film_stiffness(pa, af)
        out[f"{nt}x{nz}"] = {"load_n_at_eps_0.3": round(math.hypot(fx - fx0, fy - fy0), 3),
                             "kxx_mn_per_m": round(K[0, 0] / 1e6, 4)}
    return out


def ausman() -> dict:
    out = {}
    for rpm in (6000.0, 25000.0):
        pa = _arrays()
        b = pa.opts.bearing
        lam = 6 * b.viscosity_pa_s * rpm * math.pi / 30 * (b.radius_mm * 1e-3) ** 2 / (
            b.ambient_pa * (b.clearance_um * 1e-6) ** 2)
        Ka = linear.ausman_stiffness(b.radius_mm * 1e-3, b.length_mm * 1e-3, b.clearance_um * 1e-6,
                                 b.viscosity_pa_s, b.ambient_pa, rpm * math.pi / 30)
        row = {"bearing_number": round(lam, 3),
               "reference_kxx_kyx_kn_per_m": [round(Ka[0, 0] / 1e3, 2), round(Ka[1, 0] / 1e3, 2)]}
        for nt, nz in ((32, 8), (64, 16), (128, 32)):
            pa = _arrays(grid={"n_theta": nt, "n_z": nz})
            pa.set_block(rpm, 4.0)
            K = an.film_stiffness(pa, np.zeros(4), de=0.01e-6)
            row[f"{nt}x{nz}"] = [round(K[0, 0] / 1e3, 2), round(K[1, 0] / 1e3, 2),
                                 round(100 * abs(K[0, 0] / Ka[0, 0] - 1), 2),
                                 round(100 * abs(K[1, 0] / Ka[1, 0] - 1), 2)]
        out[f"{rpm:g}_rpm"] = row
    return out


def operating_range() -> dict:
    out = {}
    for rpm in (0.0, 3000.0, 6000.0):
        for p in (3.0, 4.0, 5.0, 7.0):
            pa = _arrays(omega_rpm=rpm, p_inj_bar=p)
            af = an.valve_area_fractions(pa.opts, 5.0)
            an.rest(pa, 5.0)
            K = an.film_stiffness(pa, af, x0=tuple(pa.stsc[L.ST_XB:L.ST_XB + 2]))
            lm = linear.linear_modes(pa, af)
            out[f"{rpm:g}rpm_{p:g}bar"] = {
                "K_mn_per_m": (K / 1e6).round(4).tolist(),
                "circulatory_kn_per_m": round(0.5 * (K[0, 1] - K[1, 0]) / 1e3, 2),
                "modes_hz": lm.freq_hz.round(1).tolist(), "zeta": lm.zeta.round(4).tolist(),
                "forward": lm.forward.tolist()}
    return out


def mass_balance() -> dict:
    out = {}
    for newton in (1, 2, 8):
        pa = _arrays(omega_rpm=3000.0, newton_iterations=newton)
        an.rest(pa, 5.0)
        sc = pa.stsc
        b0, in0, out0 = an.bdf2_mass(pa), sc[L.ST_MIN], sc[L.ST_MOUT]
        d = np.full((300, 4), 5.0)
        d[50:150, 0] = 7.0
        d[100:, 3] = 3.0
        pa.params[L.H_IMP_AXIS], pa.params[L.H_IMP_PEAK], pa.params[L.H_IMP_DUR] = 1.0, 30.0, 1e-3
        pa.params[L.H_IMP_SEQ] += 1                     # a 30 N hammer pulse on y, as the test
        k.run_batch(pa.state, pa.params, d, np.zeros((300, N_IN)))
        net = (sc[L.ST_MIN] - in0) - (sc[L.ST_MOUT] - out0)
        out[f"newton_{newton}"] = float(abs(an.bdf2_mass(pa) - b0 - net) / (sc[L.ST_MIN] - in0))
    return out


def kernel_cpu_us(n: int = 5000) -> float:
    pa = _arrays()
    an.rest(pa, 5.0)
    d = np.full((n, 4), 5.0)
    f = np.zeros((n, N_IN))
    k.run_batch(pa.state, pa.params, d[:10], f[:10])
    best = math.inf
    for _ in range(3):
        t = time.process_time()
        k.run_batch(pa.state, pa.params, d, f)
        best = min(best, time.process_time() - t)
    return round(best / n * 1e6, 2)


def main() -> int:
    print(json.dumps({"grid_convergence_4bar": grid_convergence(), "ausman": ausman(),
                      "operating_range": operating_range(),
                      "mass_balance_relative": mass_balance(),
                      "kernel_cpu_us_per_step": kernel_cpu_us()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
