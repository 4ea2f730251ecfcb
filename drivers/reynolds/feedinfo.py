"""``python -m rigd_drivers.reynolds.feedinfo``: the static load and feed-path figures as JSON.

Prints the tables of docs/plant.md ("Static load", "Feed path"): the equilibrium under gravity
(eccentricity, stiffness, modes) over P_I, the restrictor–film balance of the lumped theory
against the full film across the valve's choke, and the pneumatic-hammer band of the lumped
criterion against the full linearised plant (≈ 2 min).
"""

from __future__ import annotations

import json
import math
import sys

from rigd_drivers.reynolds import analysis as an
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds import linear
from rigd_drivers.reynolds import lumped as lu
from rigd_drivers.reynolds.params import P_ATM

QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}
C = 25e-6


def equilibrium_table(opts: dict = QUIET) -> dict:
    """ε, K and the journal modes at rest under gravity, Ω = 0, valves at r0 = 5 V."""
    out = {}
    for p in (3.0, 4.0, 5.0, 7.0):
        pa = an.make_arrays(opts, p_inj_bar=p)
        try:
            an.rest(pa, 5.0)
        except RuntimeError as e:                 # the load exceeds the film's capacity
            out[f"{p:g}bar"] = {"no_equilibrium": str(e)}
            continue
        af = an.valve_area_fractions(pa.opts, 5.0)
        xb = pa.stsc[L.ST_XB:L.ST_XB + 2]
        K = an.film_stiffness(pa, af, x0=tuple(xb))
        lm = linear.linear_modes(pa, af)
        jx, jy = lm.of_axis("x"), lm.of_axis("y")
        out[f"{p:g}bar"] = {
            "eccentricity": (xb / C).round(3).tolist(),
            "kxx_kyy_mn_per_m": [round(K[0, 0] / 1e6, 3), round(K[1, 1] / 1e6, 3)],
            "kyy_over_kxx": round(K[1, 1] / K[0, 0], 3),
            "rest_disc_um": an.rest_position(pa)["disc_um"],
            "chamber_over_supply": (pa.pc / (p * 1e5 + P_ATM)).round(3).tolist(),
            "mode_x_hz_zeta": [round(lm.freq_hz[jx], 1), round(lm.zeta[jx], 4)],
            "mode_y_hz_zeta": [round(lm.freq_hz[jy], 1), round(lm.zeta[jy], 4)]}
    return out


def balance_table(opts: dict = QUIET) -> dict:
    """Full film vs the lumped restrictor–film balance (constants from 4 bar), weightless."""
    fb = lu.feed_balance(opts, 4.0)
    out = {"film_conductance_kg_per_s_pa2": fb.g_film, "effective_area_m2": fb.area_eff}
    for p in (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 7.0):
        ps = p * 1e5 + P_ATM
        pa = an.make_arrays({**opts, "load": {"gravity_m_s2": 0.0}}, p_inj_bar=p)
        af = an.valve_area_fractions(pa.opts, 5.0)
        an.steady(pa, 0.0, 0.0, af)
        pc = pa.pc[1] / ps
        pm = (pa.wts.reshape(4, -1) @ pa.p)[1] / pa.pc[1]
        K = an.film_stiffness(pa, af)
        _, fx, _ = an.steady(pa, 0.4 * C, 0.0, af)
        lpc, lpm = fb.feed_pressures(ps, C)
        out[f"{p:g}bar"] = {
            "chamber_over_supply_full_lumped": [round(pc, 3), round(lpc / ps, 3)],
            "patch_over_chamber_full_lumped": [round(pm, 3), round(lpm / lpc, 3)],
            "kxx_mn_per_m_full_lumped": [round(K[0, 0] / 1e6, 3),
                                         round(fb.stiffness(ps) / 1e6, 3)],
            "load_n_at_eps_0.4_full_lumped": [round(-fx, 1), round(fb.load(ps, 0.4), 1)]}
    return out


def hammer_table(opts: dict = QUIET, p_inj_bar: float = 4.0) -> dict:
    """Lumped unstable chamber volumes vs the full plant's mode damping over the volume."""
    th = lu.hammer_theory(opts, p_inj_bar)
    out = {ax: {"k0_mn_per_m": round(t.k0 / 1e6, 3), "kinf_mn_per_m": round(t.kinf / 1e6, 3),
                "mass_kg": round(t.mass, 2), "damping_n_s_per_m": round(t.damping, 1),
                "tau_us_per_mm3": round(t.tau_per_mm3 * 1e6, 2),
                "unstable_band_mm3": None if t.band_mm3 is None else
                [round(v, 2) for v in t.band_mm3]} for ax, t in th.items()}
    rows = {}
    for v in (0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0,
              3000.0):
        o = {**opts, "feed": {**opts.get("feed", {}), "chamber_volume_mm3": v}}
        pa = an.make_arrays(o, p_inj_bar=p_inj_bar)
        an.rest(pa, 5.0)
        lm = linear.linear_modes(pa, an.valve_area_fractions(pa.opts, 5.0))
        rows[f"{v:g}"] = {ax: {"full_hz_zeta": [round(lm.freq_hz[lm.of_axis(ax)], 1),
                                                round(lm.zeta[lm.of_axis(ax)], 4)],
                               "lumped_unstable": bool(th[ax].unstable(v))} for ax in th}
    out["volumes_mm3"] = rows
    return out


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    inherent = {**QUIET, "feed": {"compensation": "inherent"}}
    out = {"equilibrium_orifice": equilibrium_table(),
           "equilibrium_inherent": equilibrium_table(inherent),
           "balance_orifice": balance_table(),
           "balance_inherent": balance_table(inherent),
           "hammer_orifice_4bar": hammer_table()}
    print(json.dumps(out, indent=1, default=lambda v: None if not math.isfinite(v) else v))
    return 0


if __name__ == "__main__":
    sys.exit(main())
