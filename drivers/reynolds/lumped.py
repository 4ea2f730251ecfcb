"""Lumped-parameter theory of the feed path: the pneumatic-hammer criterion.

The classical analysis of pneumatic hammer in externally pressurised gas bearings (Roudebush,
NACA TN 4095, 1957; Licht, Fuller & Sternlicht, Trans. ASME 80, 1958; Powell, *Design of
Aerostatic Bearings*, 1970, ch. 7) lumps the bearing into a mass on a gas spring whose feed
volume lags: at fixed volume pressure the film gives the *instantaneous* stiffness k_∞, once
the volume has filled the *static* stiffness k_0, with the volume's first-order time constant
τ in between. With the film's own (squeeze) damping d and the journal's effective mass m::

    m s² + d s + k_∞ + (k_0 − k_∞)/(τ s + 1) = 0
    ⇔ τ m s³ + (m + τ d) s² + (d + τ k_∞) s + k_0 = 0

and Routh–Hurwitz: stable ⇔ (m + τ d)(d + τ k_∞) > τ m k_0. Hammer needs k_0 > k_∞ (the
volume stiffens the bearing statically, and late) and occurs for τ between the two roots of
d k_∞ τ² − (m (k_0 − k_∞) − d²) τ + m d = 0 — small volumes follow the film, large ones hold
their pressure. :func:`hammer_theory` takes k_0, k_∞ and τ from static solutions of the full
film (:mod:`rigd_drivers.reynolds.analysis`), m and d from its mode with a negligible chamber,
and returns the chamber volumes the lumped theory calls unstable; the tests hold the full
linearised plant against it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigd_drivers.reynolds import analysis as an
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds import linear
from rigd_drivers.reynolds.feed import NFW, feed_flows
from rigd_drivers.reynolds.film import G_RT


@dataclass
class HammerTheory:
    """Lumped coefficients of one axis and the unstable chamber-volume band (mm³)."""

    axis: str
    k0: float                 # static stiffness (chambers settled), N/m
    kinf: float               # stiffness at frozen chamber pressures, N/m
    mass: float               # effective journal mass of the axis' mode, kg
    damping: float            # film damping of the mode without chamber lag, N s/m
    tau_per_mm3: float        # chamber time constant per mm³ of volume, s
    band_mm3: tuple[float, float] | None   # unstable volumes; None: stable at every volume

    def unstable(self, volume_mm3: float) -> bool:
        """Routh–Hurwitz of the lumped cubic at this chamber volume."""
        t = self.tau_per_mm3 * volume_mm3
        m, d = self.mass, self.damping
        return (m + t * d) * (d + t * self.kinf) <= t * m * self.k0


def _chamber_conductance(pa: an.PlantArrays, afrac, v: int, dp: float = 50.0) -> float:
    """g = ∂(ṁ_f − ṁ_v)/∂p_c of chamber v (kg/(s Pa)) with the film settled around it (the
    other chambers held): the rate at which a chamber pressure error drains."""
    p0, c0 = pa.p.copy(), pa.pc.copy()
    xb, yb = pa.stsc[L.ST_XB:L.ST_XB + 2]
    sc = pa.scalars
    out = []
    for s in (1.0, -1.0):
        pa.p[:] = p0
        pa.pc[:] = c0
        pa.pc[v] += s * dp
        an.steady(pa, xb, yb, afrac, frozen=True)
        pm = pa.wts.reshape(4, -1) @ pa.p
        md, dmd, fw = np.zeros(4), np.zeros(4), np.zeros(NFW * 4)
        feed_flows(pa.geo, pm, pa.pc.copy(), xb, yb, sc[L.SC_PSUP], np.asarray(afrac, float),
                   md, dmd, fw)
        out.append(md[v] - fw[NFW * v])
    pa.p[:] = p0
    pa.pc[:] = c0
    return (out[0] - out[1]) / (2 * dp)


def hammer_theory(opts: dict, p_inj_bar: float, drive_v: float = 5.0,
                  small_volume_mm3: float = 0.1) -> dict[str, HammerTheory]:
    """The lumped pneumatic-hammer prediction for both axes at (P_I, Ω = opts' speed).

    k_0, k_∞, τ from the plant with the options' feed path; m, d from the linearised mode of
    each axis with a negligible chamber (``small_volume_mm3``): m = k_0/ω², d = 2ζωm.
    """
    base = {**opts, "feed": {**opts.get("feed", {}), "chamber_volume_mm3": small_volume_mm3}}
    pa = an.make_arrays(base, p_inj_bar=p_inj_bar)
    an.rest(pa, drive_v)
    af = an.valve_area_fractions(pa.opts, drive_v)
    x0 = tuple(pa.stsc[L.ST_XB:L.ST_XB + 2])
    K0 = an.film_stiffness(pa, af, x0)
    Kf = an.film_stiffness(pa, af, x0, frozen=True)
    lm = linear.linear_modes(pa, af)
    rt = pa.geo[G_RT]
    out = {}
    for ax, (i, chambers) in {"x": (0, (1, 3)), "y": (1, (0, 2))}.items():
        j = lm.of_axis(ax)                         # the journal mode of this axis
        w = 2 * math.pi * lm.freq_hz[j]
        m = K0[i, i] / w ** 2
        d = 2 * lm.zeta[j] * w * m
        g = np.mean([_chamber_conductance(pa, af, v) for v in chambers])
        tau = 1e-9 / rt / g                           # cap per mm³ / g
        k0, kf = K0[i, i], Kf[i, i]
        a, b, c = d * kf, -(m * (k0 - kf) - d * d), m * d
        disc = b * b - 4 * a * c
        band = None
        if -b > 0 and disc > 0:
            t1 = (-b - math.sqrt(disc)) / (2 * a)
            t2 = (-b + math.sqrt(disc)) / (2 * a)
            band = (t1 / tau, t2 / tau)
        out[ax] = HammerTheory(ax, k0, kf, m, d, tau, band)
    return out


# --- the classical restrictor–film balance ---------------------------------------------------
@dataclass
class FeedBalance:
    """Lumped aerostatic bearing of one axis (two opposed feeds): each feed a valve and a feed
    hole in series into a film whose outflow is G (h/c)³ (p̄² − p_a²) — the Poiseuille p² law
    of a feed point (Gross 1962; Powell 1970, ch. 3) — and the axis load A_e (p̄₋ − p̄₊)."""

    g_film: float          # film conductance at the concentric gap, kg/(s Pa²)
    area_eff: float        # effective area, m²
    cda_valve: float       # C_d A of the valve at its rest opening, m²
    cda_hole: float        # orifice: C_d π d²/4 (m²); inherent: C_d π d (m)
    inherent: bool
    clearance: float
    p_a: float
    rt: float

    def feed_pressures(self, p_sup: float, h: float) -> tuple[float, float]:
        """(p_c, p̄) of one feed at film thickness h: valve flow = hole flow = film flow."""
        from scipy.optimize import brentq

        from rigd_drivers.reynolds.feed import restriction_flow

        gam = 1.4
        ah = self.cda_hole * (h if self.inherent else 1.0)

        def chamber(pm):
            def r(pc):
                return (restriction_flow(p_sup, pc, self.cda_valve, self.rt, gam)[0]
                        - restriction_flow(pc, pm, ah, self.rt, gam)[0])
            return brentq(r, pm, p_sup, xtol=1e-9, rtol=1e-13)

        def film(pm):
            pc = chamber(pm)
            return (restriction_flow(p_sup, pc, self.cda_valve, self.rt, gam)[0]
                    - self.g_film * (h / self.clearance) ** 3 * (pm * pm - self.p_a ** 2))

        pm = brentq(film, self.p_a * (1 + 1e-9), p_sup * (1 - 1e-9), xtol=1e-9, rtol=1e-13)
        return chamber(pm), pm

    def load(self, p_sup: float, eps: float) -> float:
        """Axis load (N) at eccentricity ε towards one feed."""
        c = self.clearance
        return self.area_eff * (self.feed_pressures(p_sup, c * (1 - eps))[1]
                                - self.feed_pressures(p_sup, c * (1 + eps))[1])

    def stiffness(self, p_sup: float, de: float = 1e-3) -> float:
        """Concentric axis stiffness (N/m)."""
        return self.load(p_sup, de) / (de * self.clearance)


def feed_balance(opts: dict, p_inj_bar: float = 4.0, drive_v: float = 5.0) -> FeedBalance:
    """The lumped model of the x axis, its two constants (film conductance, effective area)
    taken from the full film at one supply pressure (weightless, concentric)."""
    from rigd_drivers.reynolds.params import P_ATM

    o = {**opts, "load": {"gravity_m_s2": 0.0}}
    pa = an.make_arrays(o, p_inj_bar=p_inj_bar)
    af = an.valve_area_fractions(pa.opts, drive_v)
    an.steady(pa, 0.0, 0.0, af)
    pm = pa.wts.reshape(4, -1) @ pa.p
    sc = pa.scalars
    md, dmd, fw = np.zeros(4), np.zeros(4), np.zeros(NFW * 4)
    feed_flows(pa.geo, pm, pa.pc.copy(), 0.0, 0.0, sc[L.SC_PSUP], af, md, dmd, fw)
    geo = pa.geo
    p_a = geo[7]
    xs = (1, 3)                                          # valves 2 (+x) and 4 (−x)
    g = float(np.mean([md[v] / (pm[v] ** 2 - p_a ** 2) for v in xs]))
    fb = FeedBalance(g, 1.0, float(np.mean(af[list(xs)])) * geo[11], geo[12],
                     geo[13] != 0.0, geo[5], p_a, geo[9])
    K = an.film_stiffness(pa, af)
    fb.area_eff = K[0, 0] / fb.stiffness(p_inj_bar * 1e5 + P_ATM)
    return fb
