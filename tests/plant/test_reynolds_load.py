"""Static load (gravity, disc force) and the feed path of the physics-grade plant.

docs/plant.md, "Static load" and "Feed path", lists the figures these tests hold.
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

from rigd.frame import IN_E_X, IN_E_Y, N_IN
from rigd_drivers.reynolds import analysis as an
from rigd_drivers.reynolds import feed as fd
from rigd_drivers.reynolds import kernel as k
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds import linear
from rigd_drivers.reynolds.driver import ReynoldsPlantDriver
from rigd_drivers.reynolds.params import P_ATM
from rigd_drivers.reynolds.shaft import STEEL_RHO, ShaftGeometry

QUIET = {"noise": {"e_um": 0.0, "y_p_v": 0.0}}
C = 25e-6
CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim_reynolds.yaml"


def _rest(p_inj=4.0, omega=0.0, **opts):
    pa = an.make_arrays({**QUIET, "omega_rpm": omega, **opts}, p_inj_bar=p_inj)
    an.rest(pa, 5.0)
    return pa


def _stiffness_at_rest(pa):
    af = an.valve_area_fractions(pa.opts, 5.0)
    return an.film_stiffness(pa, af, x0=tuple(pa.stsc[L.ST_XB:L.ST_XB + 2]))


def test_journal_load_is_the_disc_lever_and_the_shaft_weight():
    """The film carries what statics of the rigid shaft on the ball bearing say: moments of the
    disc's and the shaft's weight about the ball bearing over the journal's lever (≈ 71 N)."""
    g = ShaftGeometry()
    m_shaft = STEEL_RHO * np.pi * g.diameter ** 2 / 4 * g.length
    w = 9.81 * (g.disc_mass * (g.z_disc - g.z_ball) + m_shaft * (g.length / 2 - g.z_ball)) / (
        g.z_journal - g.z_ball)
    pa = an.make_arrays(QUIET)
    W, _ = an.static_load(pa)
    assert 60.0 < w < 80.0
    assert W[0] == pytest.approx(0.0, abs=1e-9)
    assert W[1] == pytest.approx(w, rel=0.03)     # FE nodes snap the journal 8 mm off 380 mm
    # a disc force adds its own lever; gravity off leaves only it
    pa = an.make_arrays({**QUIET, "load": {"gravity_m_s2": 0.0, "disc_n": [10.0, 0.0]}})
    W, _ = an.static_load(pa)
    assert W[0] == pytest.approx(-10.0 * (g.z_disc - g.z_ball) / (g.z_journal - g.z_ball),
                                 rel=0.03)
    assert W[1] == pytest.approx(0.0, abs=1e-9)


def test_rest_is_the_equilibrium_under_gravity():
    """At rest the whole semi-discrete ODE (film, chambers, shaft) is stationary, the journal
    sits below the centre and the stepped plant stays there."""
    pa = _rest()
    ecc = pa.stsc[L.ST_XB:L.ST_XB + 2] / C
    assert ecc[1] < -0.2 and abs(ecc[0]) < 0.02
    af = an.valve_area_fractions(pa.opts, 5.0)
    m = pa.lay.m
    o = pa.lay.st
    y0 = np.concatenate([pa.p, pa.pc, pa.state[o[L.T_Q]:o[L.T_Q] + m], np.zeros(m)])
    f = linear.ode_rhs(pa, y0, af)
    n = pa.n
    # film and chamber pressure rates (Pa/s) against one sub-step's worth of p_a, shaft
    # accelerations against the gravity term they balance
    assert np.abs(f[:n + 4]).max() * 50e-6 < 1e-6 * pa.geo[7]
    grav = np.abs(pa.params_block(L.O_FST, m)).max()
    assert np.abs(f[n + 4 + m:]).max() < 1e-6 * grav
    e0 = np.zeros(N_IN)
    k.plant_sense(pa.state, pa.params, e0)
    fr = np.zeros((200, N_IN))
    k.run_batch(pa.state, pa.params, np.full((200, 4), 5.0), fr)
    assert np.abs(fr[:, [IN_E_X, IN_E_Y]] - e0[[IN_E_X, IN_E_Y]]).max() < 1e-3    # µm


def test_gravity_makes_the_bearing_stiffer_vertically_and_pressure_lifts_the_journal():
    """Weightless, the rig is isotropic at the centre (but for the valves' spread); under
    gravity the journal sits lower at lower supply pressure and the vertical stiffness exceeds
    the horizontal one."""
    K0 = _stiffness_at_rest(_rest(load={"gravity_m_s2": 0.0}))
    assert K0[1, 1] == pytest.approx(K0[0, 0], rel=0.05)     # the valves differ by ±3 %
    eps = {}
    for p in (4.0, 7.0):
        pa = _rest(p)
        eps[p] = -pa.stsc[L.ST_XB + 1] / C
        K = _stiffness_at_rest(pa)
        assert K[1, 1] > 1.1 * K[0, 0]
    assert eps[7.0] < eps[4.0] < 0.6


def test_supervisor_centre_of_the_shipped_config_is_the_rest_position():
    """config/sim_reynolds.yaml centres the supervisor's displacement check on the shaft's rest
    under gravity at its operating point (within 0.5 µm)."""
    cfg = yaml.safe_load(CONFIG.read_text())
    opts = cfg["drivers"]["fast"]["options"]
    d = ReynoldsPlantDriver(opts)
    rest = d.describe()["rest_um"]
    assert cfg["supervisor"]["centre_um"] == pytest.approx(rest, abs=0.5)
    assert rest[1] < -5.0                                  # really below the bearing centre


@pytest.mark.parametrize("comp", ["orifice", "inherent"])
def test_chambers_at_rest_pass_what_the_valves_deliver_and_the_film_carries_it_out(comp):
    """Steady state: valve flow = feed-hole flow per chamber (both from the restriction formula
    at the solved pressures) and the four feed flows = the film's end outflow."""
    pa = _rest(feed={"compensation": comp})
    af = an.valve_area_fractions(pa.opts, 5.0)
    xb, yb = pa.stsc[L.ST_XB:L.ST_XB + 2]
    pm = pa.wts.reshape(4, -1) @ pa.p
    ps = 4e5 + P_ATM
    geo = pa.geo
    rt = geo[9]
    tot = 0.0
    for v in range(4):
        mv = fd.restriction_flow(ps, pa.pc[v], af[v] * geo[11], rt, 1.4)[0]
        h = C - xb * fd.VALVE_COS[v] - yb * fd.VALVE_SIN[v]
        area = 0.8 * np.pi * 0.4e-3 * (h if comp == "inherent" else 0.4e-3 / 4)
        mf = fd.restriction_flow(pa.pc[v], pm[v], area, rt, 1.4)[0]
        assert mv > 0 and mf == pytest.approx(mv, rel=1e-6)
        assert pm[v] < pa.pc[v] < ps
        tot += mf
    rate, chamber = linear._rates(pa, pa.p, pa.pc, xb, yb, af)
    assert np.abs(chamber).max() < 1e-9 * tot
    # out through the ends = in through the holes (× R_g T); the film rates sum to zero
    assert abs(rate.sum()) < 1e-9 * 0.5 * rt * tot


def test_inherent_compensation_feeds_through_the_curtain():
    """Inherent: the feed-hole restriction is the curtain π d h, so closing the gap under one
    hole throttles it — the chamber behind the lower hole (gap closed by gravity) rises above
    the upper one; with orifice compensation the two stay closer together."""
    spread = {}
    for comp in ("inherent", "orifice"):
        pa = _rest(feed={"compensation": comp})
        spread[comp] = (pa.pc[2] - pa.pc[0]) / (4e5 + P_ATM)        # valve 3 (−y) − valve 1
        assert spread[comp] > 0
    assert spread["inherent"] > spread["orifice"]


def test_supply_follows_a_new_pressure_at_the_regulator_slew():
    """set_operating_point(P_I): the supply ramps at `supply_slew_bar_per_s` (10 bar/s), so a
    jump from 7 to 3 bar at 6 krpm keeps the journal on its upper equilibrium; 0 jumps."""
    d = ReynoldsPlantDriver({**QUIET, "p_inj_bar": 4.0})
    sc = d._arr.stsc
    d.set_operating_point(0.0, 7.0)
    d.run(np.full((500, 4), 5.0))                               # 0.1 s
    assert (sc[L.ST_PSUP] - P_ATM) / 1e5 == pytest.approx(5.0, abs=0.01)
    d.run(np.full((1000, 4), 5.0))
    assert (sc[L.ST_PSUP] - P_ATM) / 1e5 == pytest.approx(7.0, abs=1e-9)
    d = ReynoldsPlantDriver({**QUIET, "p_inj_bar": 4.0, "supply_slew_bar_per_s": 0.0})
    d.set_operating_point(0.0, 7.0)
    d.run(np.full((2, 4), 5.0))
    assert (d._arr.stsc[L.ST_PSUP] - P_ATM) / 1e5 == pytest.approx(7.0, abs=1e-9)
