"""Static analysis of the physics-grade plant (Python around the kernels).

For tests, docs and the driver's rest state: the plant's arrays, steady film at a fixed journal
position, film force and stiffness, the static load, the equilibrium and the rest state. The
linearised system and its modes, and the classical reference: :mod:`rigd_drivers.reynolds.linear`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigd_drivers.reynolds import kernel as k
from rigd_drivers.reynolds import layout as L
from rigd_drivers.reynolds import step as S
from rigd_drivers.reynolds.film import G_AREA, G_C, G_N, NV, film_force
from rigd_drivers.reynolds.options import ReynoldsOptions
from rigd_drivers.reynolds.params import Layout, build_layout, param_block, shaft_model
from rigd_drivers.reynolds.shaft import ShaftModel


@dataclass
class PlantArrays:
    """The kernel arrays of one plant instance, plus what built them."""

    opts: ReynoldsOptions
    lay: Layout
    shaft: ShaftModel
    params: np.ndarray
    state: np.ndarray
    fs: float

    # --- views ---------------------------------------------------------------------------
    def _st(self, slot: int, size: int) -> np.ndarray:
        o = self.lay.st[slot]
        return self.state[o:o + size]

    def _blk(self, slot: int, size: int) -> np.ndarray:
        o = int(self.params[L.H_ACT]) + self.lay.block[slot]
        return self.params[o:o + size]

    @property
    def n(self) -> int:
        return self.lay.nt * self.lay.mz

    @property
    def p(self) -> np.ndarray:
        """Film pressures (view), Pa abs, k = i·mz + j."""
        return self._st(L.T_P, self.n)

    @property
    def pc(self) -> np.ndarray:
        """Chamber pressures of the four feed paths (view), Pa abs."""
        return self._st(L.T_PC, NV)

    @property
    def geo(self) -> np.ndarray:
        return self._blk(L.O_GEO, G_N)

    @property
    def cs(self) -> np.ndarray:
        return self._blk(L.O_CS, 4 * self.lay.nt)

    @property
    def wts(self) -> np.ndarray:
        return self._blk(L.O_WTS, NV * self.n)

    @property
    def scalars(self) -> np.ndarray:
        return self._blk(L.O_SC, L.N_SC)

    @property
    def stsc(self) -> np.ndarray:
        return self._st(L.T_SC, L.N_STSC)

    @property
    def afrac(self) -> np.ndarray:
        return self._st(L.W_AF, NV)

    def params_block(self, slot: int, size: int) -> np.ndarray:
        """A view of the active parameter block at ``slot`` (an ``O_*`` slot)."""
        return self._blk(slot, size)

    def set_block(self, omega_rpm: float, p_inj_bar: float) -> None:
        """Write the active (and staged) parameter block for (Ω, P_I) directly."""
        blk = param_block(self.opts, self.lay, self.shaft, omega_rpm, p_inj_bar, self.fs)
        na = blk.size
        a = int(self.params[L.H_ACT])
        s = int(self.params[L.H_STG])
        self.params[a:a + na] = blk
        self.params[s:s + na] = blk


def make_arrays(opts: ReynoldsOptions | dict | None = None, fs: float = 5000.0,
                omega_rpm: float | None = None, p_inj_bar: float | None = None) -> PlantArrays:
    """Allocate and fill params/state for the options (film at ambient, shaft centred)."""
    if not isinstance(opts, ReynoldsOptions):
        opts = ReynoldsOptions.model_validate(opts or {})
    nt, mz = opts.grid.n_theta, opts.grid.n_z // 2
    shaft = shaft_model(opts)
    lay = build_layout(nt, mz, 2 * shaft.n_modes)
    params = np.zeros(lay.n_params)
    params[:L.N_HEADER] = lay.header
    state = np.zeros(lay.n_state)
    pa = PlantArrays(opts, lay, shaft, params, state, fs)
    pa.set_block(opts.omega_rpm if omega_rpm is None else omega_rpm,
                 opts.p_inj_bar if p_inj_bar is None else p_inj_bar)
    pa.p[:] = pa.geo[7]
    pa.pc[:] = pa.geo[7]
    return pa


def steady(pa: PlantArrays, xb: float, yb: float, afrac, *, tol: float = 1e-12,
           max_it: int = 60, frozen: bool = False) -> tuple[np.ndarray, float, float]:
    """Steady film at the journal position (xb, yb) m with orifice area fractions ``afrac``
    (and the chambers at their steady pressures, or held where they are with ``frozen``).

    Returns (p copy, F_x, F_y) (Pa, N). Raises RuntimeError if Newton does not converge.
    """
    pa.afrac[:] = afrac
    upd = S.steady_film(pa.state, pa.params, float(xb), float(yb), max_it, tol, frozen)
    if not upd < 1e-9:
        raise RuntimeError(f"steady film did not converge (last update {upd:.2e} p_a)")
    fx, fy = film_force(pa.geo, pa.cs, pa.p)
    return pa.p.copy(), fx, fy


def film_stiffness(pa: PlantArrays, afrac, x0=(0.0, 0.0), de: float = 0.05e-6, *,
                   frozen: bool = False) -> np.ndarray:
    """Static film stiffness K = −∂F/∂x_b (N/m, 2 × 2) at x0 by central differences (with
    ``frozen``: the chamber pressures held, the film's stiffness faster than the chambers)."""
    K = np.zeros((2, 2))
    p0 = pa.p.copy()
    c0 = pa.pc.copy()
    for j in range(2):
        x = np.array(x0, float)
        x[j] += de
        pa.p[:] = p0
        pa.pc[:] = c0
        _, fxp, fyp = steady(pa, x[0], x[1], afrac, frozen=frozen)
        x[j] -= 2 * de
        pa.p[:] = p0
        pa.pc[:] = c0
        _, fxm, fym = steady(pa, x[0], x[1], afrac, frozen=frozen)
        K[0, j] = -(fxp - fxm) / (2 * de)
        K[1, j] = -(fyp - fym) / (2 * de)
    pa.p[:] = p0
    pa.pc[:] = c0
    return K


def valve_area_fractions(opts: ReynoldsOptions, drive_v: float) -> np.ndarray:
    """Area fractions of the four valves at rest under a constant drive (V)."""
    from rigd_drivers.plant import physics as phys

    out = np.zeros(NV)
    for i, v in enumerate(phys.valve_params(opts.valves.f_scale)):
        out[i] = k.area_fraction(v.gain * drive_v + v.offset_v)
    return out


def static_load(pa: PlantArrays) -> tuple[np.ndarray, np.ndarray]:
    """The film force (N) that holds the static load, and the elastic modal response to it.

    The static modal force f (gravity, disc force: :meth:`ShaftModel.static_force`) must be
    balanced on the rigid (pivoting) modes by the film alone, φ_b,r W + f_r = 0 per plane;
    the elastic modes then deflect by q_e = K_e⁻¹ (f_e + φ_b,e W). Returns (W (2,), q_e-part of
    q (2m,) with zeros on the rigid modes).
    """
    sh = pa.shaft
    nm = sh.n_modes
    f = pa.params_block(L.O_FST, 2 * nm)
    rig = sh.rigid()
    if rig.size != 1:
        raise RuntimeError(f"expected one rigid (pivot) mode per plane, found {rig.size}")
    r = int(rig[0])
    W = np.array([-f[r] / sh.phi_journal[r], -f[nm + r] / sh.phi_journal[r]])
    q = np.zeros(2 * nm)
    for pl in range(2):
        for j in range(nm):
            if j != r:
                q[pl * nm + j] = (f[pl * nm + j] + sh.phi_journal[j] * W[pl]) / sh.omega_r[j] ** 2
    return W, q


def equilibrium(pa: PlantArrays, afrac, *, tol_n: float = 1e-9,
                load=(0.0, 0.0)) -> np.ndarray:
    """Journal position (m) where the film force equals ``load`` (N; the film holds it)."""
    x = np.zeros(2)
    W = np.asarray(load, float)
    for _ in range(30):
        _, fx, fy = steady(pa, x[0], x[1], afrac)
        r = np.array([fx, fy]) - W
        if math.hypot(*r) < tol_n * max(1.0, math.hypot(*W)):
            break
        K = film_stiffness(pa, afrac, x)
        step = np.linalg.solve(K, r)
        lim = 0.1 * pa.geo[G_C]                      # at most 0.1 c per step (nonlinear film)
        nrm = math.hypot(*step)
        if nrm > lim:
            step *= lim / nrm
        x = x + step
    else:
        raise RuntimeError(f"no film equilibrium for the load {W.tolist()} N (last {x} m)")
    steady(pa, x[0], x[1], afrac)
    return x


def rest(pa: PlantArrays, drive_v: float) -> None:
    """Put the plant at rest under a constant drive: valves, film, shaft, histories."""
    from rigd_drivers.plant import physics as phys

    pa.state[:] = 0.0
    pa.p[:] = pa.geo[7]
    pa.pc[:] = pa.geo[7]
    af = valve_area_fractions(pa.opts, drive_v)
    W, q = static_load(pa)
    xb = equilibrium(pa, af, load=W)
    o = pa.lay.st
    for i, v in enumerate(phys.valve_params(pa.opts.valves.f_scale)):
        pa.state[o[L.T_XV] + 2 * i] = v.gain * drive_v
        pa.state[o[L.T_VPREV] + i] = drive_v
    pa.state[o[L.T_AF0]:o[L.T_AF0] + NV] = af
    pa.afrac[:] = af
    n = pa.n
    pa.state[o[L.T_P1]:o[L.T_P1] + n] = pa.p
    pa.state[o[L.T_PC1]:o[L.T_PC1] + NV] = pa.pc
    pa.state[o[L.T_P2]:o[L.T_P2] + n] = pa.p
    pa.state[o[L.T_PC2]:o[L.T_PC2] + NV] = pa.pc
    psi = psi_of(pa, pa.p, xb)
    pa.state[o[L.T_PSI]:o[L.T_PSI] + n] = psi
    pa.state[o[L.T_PSI1]:o[L.T_PSI1] + n] = psi
    # shaft: the elastic deflection under the load, and the rigid pivoting carries the journal
    # the rest of the way to x_b
    m = pa.lay.m
    nm = m // 2
    r = int(pa.shaft.rigid()[0])
    phib = pa.shaft.phi_journal
    for pl in range(2):
        q[pl * nm + r] = (xb[pl] - phib @ q[pl * nm:(pl + 1) * nm]) / phib[r]
    pa.state[o[L.T_Q]:o[L.T_Q] + m] = q
    pa.state[o[L.T_Q1]:o[L.T_Q1] + m] = q
    pa.stsc[L.ST_XB:L.ST_XB + 2] = xb
    pa.stsc[L.ST_PSUP] = pa.scalars[L.SC_PSUP]
    pa.stsc[L.ST_APPLIED] = pa.params[L.H_STAGE_SEQ]
    pa.stsc[L.ST_IMP_SEEN] = pa.params[L.H_IMP_SEQ]      # a hammer blow before is not replayed


def rest_position(pa: PlantArrays) -> dict:
    """Noise-free disc (sensor) position (µm) and journal eccentricity (x_b, y_b)/c of the
    current state (after :func:`rest`: the equilibrium)."""
    m = pa.lay.m
    o = pa.lay.st
    _, Pd = pa.shaft.coupling()
    disc = Pd @ pa.state[o[L.T_Q]:o[L.T_Q] + m] * 1e6
    ecc = pa.stsc[L.ST_XB:L.ST_XB + 2] / pa.geo[G_C]
    return {"disc_um": [round(float(v), 3) for v in disc],
            "eccentricity": [round(float(v), 4) for v in ecc]}


def psi_of(pa: PlantArrays, p: np.ndarray, xb) -> np.ndarray:
    """Cell mass × R_g T, p h A (Pa m³), of the half film."""
    nt, mz = pa.lay.nt, pa.lay.mz
    cs = pa.cs
    h = pa.geo[G_C] - xb[0] * cs[:nt] - xb[1] * cs[nt:2 * nt]
    return (p.reshape(nt, mz) * h[:, None]).ravel() * pa.geo[G_AREA]


def bdf2_mass(pa: PlantArrays) -> float:
    """(3 M_n − M_{n−1})/2, M = film mass × R_g T (Pa m³): the mass of the BDF2 balance — its
    change over a run equals the cumulative inflow − outflow (``ST_MIN`` − ``ST_MOUT``)."""
    o, n = pa.lay.st, pa.n
    m0 = 2 * pa.state[o[L.T_PSI]:o[L.T_PSI] + n].sum()
    m1 = 2 * pa.state[o[L.T_PSI1]:o[L.T_PSI1] + n].sum()
    return 0.5 * (3 * m0 - m1)
