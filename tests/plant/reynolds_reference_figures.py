"""Print the figures of tests/plant/test_reynolds_references.py as one JSON object (the
"Independent references" table of docs/plant.md), computed with the tests' own references:

    .venv/bin/python tests/plant/reynolds_reference_figures.py      # ≈ 5 min idle

Also the concentric film's circulatory stiffness of tests/plant/test_reynolds_physics.py.
The tests assert bounds on these figures; this prints the figures themselves, so the docs can
state what the plant gives now. Nothing here is a test.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import test_reynolds_references as R  # noqa: E402

from rigd_drivers.reynolds import analysis as an  # noqa: E402
from rigd_drivers.reynolds.shaft import ShaftGeometry, build_shaft  # noqa: E402


def shaft() -> dict:
    sm = build_shaft(ShaftGeometry(n_modes=4))
    g, z = sm.geometry, sm.z_nodes
    zb = z[np.argmin(np.abs(z - g.z_ball))]
    zd = z[np.argmin(np.abs(z - g.z_disc))]
    zj = z[np.argmin(np.abs(z - g.z_journal))]
    f_fe = sm.omega_r[1:] / (2 * math.pi)
    f_tm, ratio_tm = R._tmm_modes(ShaftGeometry(z_journal=float(zj)), zb, zd, 1.2 * f_fe[-1])
    f_st, _ = R._tmm_modes(g, g.z_ball, g.z_disc, 1.2 * f_fe[-1])
    ratio_fe = sm.phi_journal[1:] / sm.phi_disc[1:]
    return {"fe_hz": [round(float(f), 2) for f in f_fe],
            "transfer_matrix_snapped_hz": [round(float(f), 2) for f in f_tm],
            "max_rel_diff_snapped": float(np.max(np.abs(f_tm / f_fe - 1))),
            "max_shape_ratio_diff": float(np.max(np.abs(ratio_tm / ratio_fe - 1))),
            "transfer_matrix_stated_hz": [round(float(f), 2) for f in f_st],
            "max_rel_diff_stated": float(np.max(np.abs(f_st / f_fe - 1)))}


def squeeze() -> dict:
    b = an.make_arrays({}).opts.bearing
    out = {}
    for f in (50.0, 150.0, 400.0):
        za = R._squeeze_analytic(f, b)
        out[f"{f:g}_hz"] = {f"{g[0]}x{g[1]}": round(100 * abs(R._squeeze_numeric(g, f) / za - 1),
                                                    2) for g in ((32, 8), (64, 16))}
    return out


def hybrid_order() -> dict:
    out = {}
    for eps in (0.3, 0.6):
        r = np.array([R._hybrid(g, eps, R.ALIGNED) for g in R.GRIDS])
        out[f"eps_{eps:g}"] = {n: round(R._order(*r[:, j]), 2)
                               for j, n in enumerate(("F_x", "F_y", "k_xx", "k_yx"))}
    return out


def default_grid() -> dict:
    out = {}
    for eps in (0.3, 0.6, 0.8, 0.9):
        c, f = R._hybrid((32, 8), eps), R._hybrid((128, 32), eps)
        out[f"eps_{eps:g}"] = {"F_x_percent": round(100 * abs(c[0] / f[0] - 1), 1),
                               "F_y_percent": round(100 * abs(c[1] / f[1] - 1), 1),
                               "F_x_fine_n": round(float(f[0]), 1)}
    return out


def circulatory_concentric() -> dict:
    """½(k_xy − k_yx) (kN/m) of the concentric film at 4 bar, valves at r0 (as
    tests/plant/test_reynolds_physics.py::test_cross_coupled_stiffness_grows_with_speed)."""
    out = {}
    for rpm in (0.0, 3000.0, 6000.0):
        pa = an.make_arrays({"omega_rpm": rpm}, p_inj_bar=4.0)
        af = an.valve_area_fractions(pa.opts, 5.0)
        an.steady(pa, 0.0, 0.0, af)
        K = an.film_stiffness(pa, af)
        out[f"{rpm:g}_rpm"] = round(float(0.5 * (K[0, 1] - K[1, 0])) / 1e3, 1)
    return out


def main() -> int:
    out = {}
    for name, fn in (("circulatory_concentric_kn_per_m", circulatory_concentric),
                     ("shaft_modes", shaft), ("squeeze_error_percent", squeeze),
                     ("hybrid_observed_order", hybrid_order),
                     ("default_grid_vs_128x32", default_grid)):
        out[name] = fn()
        print(f"{name} done", file=sys.stderr, flush=True)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
