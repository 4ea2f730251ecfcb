"""A measured structure under a shaker with a bolted joint in one mode's load path.

The structure is written in modal coordinates q_i (displacement per mode, m), excited by one
shaker force f (N) and measured by accelerometers (m/s²)::

    q̈_i + 2 ζ_i ω_i q̇_i + ω_i² q_i = b_i f − s_i g(d, z),      d = Σ_i s_i q_i
    a_k = Σ_i c_ki q̈_i

``b`` (the modal participation of the shaker), ``c`` (the mode shapes at the sensors) and
``s`` (the joint's share of each mode: its load path) are fixed by the seed; ``s`` is 1 for
the joint's mode and ``leak`` (small) for the others, so the joint acts on that mode's
coordinate first, as a structural dynamicist models a joint (a nonlinear mode).

The joint force ``g`` is one of

* ``"iwan"`` — an Iwan element: ``n_slip`` Jenkins elements in parallel (a spring of
  stiffness ``k_joint / n_slip`` in series with a Coulomb slider), their slip forces spread
  evenly up to ``f_slip`` (N per unit modal mass). Below the first slip force the joint is
  stuck and adds ``k_joint`` to the mode's stiffness; as the amplitude grows more sliders
  slip: the mode **softens** and the hysteresis loops **dissipate** (damping rises). One
  element (``n_slip=1``) is the Jenkins element (macro-slip only).
* ``"clearance"`` — a dead-zone spring: no force inside the gap ``±gap`` (m), ``k_joint``
  beyond it: the mode **stiffens** with amplitude.

The force is a periodic random-phase multisine over ``band`` (Hz), continuous in time: it
is evaluated between samples by band-limited (FFT) interpolation of the same spectrum, so a
model that holds it over each sample is wrong by construction — as a measured force is. The
ODE is integrated by RK4 on ``sub`` steps per sample, the sliders updated by return mapping
(elastic predictor, slip corrector) at the end of each step.

Nothing here uses rigd: the records test rigd's diagnosis on a system it has never seen.
"""

from __future__ import annotations

import numba
import numpy as np

from tests.gen.record import Generated, add_noise

#: the five modes of :func:`joint_structure`, joint slipped (Hz, ζ)
FIVE_MODES = ((7.0, 0.004), (15.8, 0.006), (27.5, 0.008), (44.0, 0.01), (66.0, 0.012))


def _periodic_multisine(n: int, fs: float, band, rms: float, rng, sub: int):
    """The force at the samples (n,) and on the integration grid (n·sub,): one period of a
    random-phase multisine on the DFT grid of ``n`` samples, flat over ``band``."""
    k = np.arange(n // 2 + 1)
    f = k * fs / n
    lines = (f >= band[0]) & (f <= band[1])
    spec = np.zeros(len(k), complex)
    spec[lines] = np.exp(2j * np.pi * rng.uniform(size=lines.sum()))
    x = np.fft.irfft(spec, n)
    scale = rms / np.std(x)
    fine_spec = np.zeros(n * sub // 2 + 1, complex)
    fine_spec[: len(k)] = spec * sub        # same lines, sub times the length: exact values
    fine = np.fft.irfft(fine_spec, n * sub)
    return x * scale, fine * scale


@numba.njit(cache=True)
def _joint_force(d, z, kind, k_el, f_el, gap, k_joint):  # pragma: no cover - compiled
    """Joint force for the relative displacement ``d`` from the committed slider positions
    ``z`` (not changed); kind 0 = Iwan, 1 = clearance."""
    if kind == 1:
        if d > gap:
            return k_joint * (d - gap)
        if d < -gap:
            return k_joint * (d + gap)
        return 0.0
    g = 0.0
    for e in range(z.shape[0]):
        fe = k_el * (d - z[e])
        if fe > f_el[e]:
            fe = f_el[e]
        elif fe < -f_el[e]:
            fe = -f_el[e]
        g += fe
    return g


@numba.njit(cache=True)
def _integrate(force, sub, h, w, zeta, b, s, c, kind, k_el, f_el, gap, k_joint
               ):  # pragma: no cover - compiled
    """RK4 over the fine force grid; returns accelerations at the samples (n, ny) and the
    joint's relative displacement at the samples (n,)."""
    m = w.shape[0]
    n = force.shape[0] // sub
    ny = c.shape[0]
    acc = np.empty((n, ny))
    rel = np.empty(n)
    q = np.zeros(m)
    v = np.zeros(m)
    z = np.zeros(f_el.shape[0])
    kq = np.empty((4, m))
    kv = np.empty((4, m))
    qs = np.empty(m)
    vs = np.empty(m)
    for i in range(n):
        # the sample: acceleration from the state at the sample instant
        d = 0.0
        for j in range(m):
            d += s[j] * q[j]
        g = _joint_force(d, z, kind, k_el, f_el, gap, k_joint)
        f0 = force[i * sub]
        for r in range(ny):
            a = 0.0
            for j in range(m):
                a += c[r, j] * (b[j] * f0 - s[j] * g - 2.0 * zeta[j] * w[j] * v[j]
                                - w[j] * w[j] * q[j])
            acc[i, r] = a
        rel[i] = d
        for t in range(sub):
            idx = i * sub + t
            fa = force[idx]
            fb = force[(idx + 1) % force.shape[0]]
            for st in range(4):
                cw = 0.0 if st == 0 else (0.5 if st < 3 else 1.0)
                ft = fa if st == 0 else (0.5 * (fa + fb) if st < 3 else fb)
                for j in range(m):
                    qs[j] = q[j] + cw * h * (kq[st - 1, j] if st else 0.0)
                    vs[j] = v[j] + cw * h * (kv[st - 1, j] if st else 0.0)
                d = 0.0
                for j in range(m):
                    d += s[j] * qs[j]
                g = _joint_force(d, z, kind, k_el, f_el, gap, k_joint)
                for j in range(m):
                    kq[st, j] = vs[j]
                    kv[st, j] = (b[j] * ft - s[j] * g - 2.0 * zeta[j] * w[j] * vs[j]
                                 - w[j] * w[j] * qs[j])
            for j in range(m):
                q[j] += h / 6.0 * (kq[0, j] + 2.0 * kq[1, j] + 2.0 * kq[2, j] + kq[3, j])
                v[j] += h / 6.0 * (kv[0, j] + 2.0 * kv[1, j] + 2.0 * kv[2, j] + kv[3, j])
            # commit the sliders (return mapping at the end of the step)
            if kind == 0:
                d = 0.0
                for j in range(m):
                    d += s[j] * q[j]
                for e in range(z.shape[0]):
                    fe = k_el * (d - z[e])
                    if fe > f_el[e]:
                        z[e] = d - f_el[e] / k_el
                    elif fe < -f_el[e]:
                        z[e] = d + f_el[e] / k_el
    return acc, rel


def joint_structure(level: float = 1.0, joint: str = "iwan", modes=FIVE_MODES,
                    joint_mode: int = 0, n_outputs: int = 3, fs: float = 400.0,
                    n: int = 16384, periods: int = 1, band=(3.0, 40.0),
                    force_rms: float = 1.0, k_ratio: float = 0.25, f_slip: float = 1.5,
                    n_slip: int = 8, gap: float = 3e-3, leak: float = 0.05,
                    snr_db: float = 40.0, seed: int = 0, sub: int = 10) -> Generated:
    """One record of the jointed structure at force level ``level`` (× ``force_rms`` N).

    Parameters
    ----------
    level : float
        Force level: the shaker force's RMS is ``level * force_rms`` (N). The structure, the
        multisine's phases and the sensor noise's seed do not change with the level.
    joint : {"iwan", "clearance"}
        The joint (module docstring).
    modes : sequence of (float, float)
        The modes' (frequency Hz, damping ratio) with the joint slipped / open.
    joint_mode : int
        The mode whose load path carries the joint.
    n_outputs : int
        Accelerometers (1–3 are typical).
    fs : float
        Sample rate, Hz.
    n, periods : int
        Samples per multisine period, and how many periods (the first is a transient; all
        are returned).
    band : (float, float)
        The multisine's band, Hz.
    k_ratio : float
        The joint's stiffness relative to the joint mode's ω² (stuck: the mode's ω² is
        ``(1 + k_ratio)`` times the slipped one).
    f_slip : float
        The largest slider's slip force per unit modal mass (m/s²·modal unit), Iwan only.
    n_slip : int
        Jenkins elements in the Iwan element (1: a Jenkins element).
    gap : float
        The clearance's half-gap, modal displacement units (clearance only).
    leak : float
        The joint's share of the other modes' coordinates.
    snr_db : float
        Sensor noise below each channel's standard deviation, dB.

    Returns
    -------
    Generated
        ``u`` the force (N), ``y`` the accelerations (m/s²); ``truth`` with the modes (stuck
        and slipped), the joint's mode and frequency, its kind, the level and the force RMS,
        and the joint's relative displacement ``truth["joint_d"]``.
    """
    if joint not in ("iwan", "clearance"):
        raise ValueError(f"joint must be 'iwan' or 'clearance', got {joint!r}")
    rng = np.random.default_rng(seed)
    m = len(modes)
    w = np.array([2 * np.pi * f for f, _ in modes])
    zeta = np.array([z for _, z in modes])
    b = rng.choice([-1.0, 1.0], m) * rng.uniform(0.6, 1.0, m)
    c = rng.choice([-1.0, 1.0], (n_outputs, m)) * rng.uniform(0.3, 1.0, (n_outputs, m))
    s = np.full(m, leak)
    s[joint_mode] = 1.0
    k_joint = k_ratio * w[joint_mode] ** 2
    if joint == "iwan":
        kind, k_el = 0, k_joint / n_slip
        f_el = f_slip * np.arange(1, n_slip + 1) / n_slip
    else:
        kind, k_el, f_el = 1, 0.0, np.zeros(1)
    rms = level * force_rms
    phase_rng = np.random.default_rng(seed + 1)
    u1, fine1 = _periodic_multisine(n, fs, band, rms, phase_rng, sub)
    u = np.tile(u1, periods)
    fine = np.tile(fine1, periods)
    acc, rel = _integrate(fine, sub, 1.0 / (fs * sub), w, zeta, b, s, c, kind, k_el, f_el,
                          gap, k_joint)
    noise_rng = np.random.default_rng(seed + 2)
    f_j, z_j = modes[joint_mode]
    stuck = list(modes)
    if joint == "iwan":
        stuck[joint_mode] = (f_j * np.sqrt(1 + k_ratio), z_j / np.sqrt(1 + k_ratio))
    truth = dict(kind="joint_structure", joint=joint, joint_mode=joint_mode,
                 joint_f_hz=float(f_j), modes=[tuple(map(float, x)) for x in modes],
                 modes_stuck=[tuple(map(float, x)) for x in stuck], level=float(level),
                 force_rms=float(rms), band=tuple(band), k_joint=float(k_joint),
                 f_slip=float(f_slip), gap=float(gap), order=2 * m, delays=[0.0],
                 integrator=False, closed_loop=False,
                 nonlinearity=dict(site="mode", mode=joint_mode, f_hz=float(f_j),
                                   effect="friction" if joint == "iwan" else "clearance"),
                 joint_d=rel)
    outs = [f"acc{k + 1}" for k in range(n_outputs)]
    return Generated(u[:, None], add_noise(acc, snr_db, noise_rng), fs, ["force"], outs,
                     {"force": "N", **{o: "m/s^2" for o in outs}}, truth, acc)


def mode_near(g: Generated, f_guess: float, half_width: float = 0.12, output: int = 0):
    """The apparent (frequency Hz, damping ratio) of the mode near ``f_guess`` in ``g``: a
    one-mode fit of the measured receptance Y/(−ω² U) on the multisine's DFT lines within
    ±``half_width``·f_guess — (ω_n² − ω² + 2jζω_nω)·H = R, linear least squares in ω_n²,
    2ζω_n and the complex residue R. A yardstick for the generator's own physics,
    independent of rigd."""
    u, y = g.u[:, 0], g.y[:, output]
    U, Y = np.fft.rfft(u), np.fft.rfft(y)
    f = np.fft.rfftfreq(len(u), 1.0 / g.fs)
    lines = np.abs(U) > 1e-6 * np.abs(U).max()
    sel = lines & (np.abs(f - f_guess) <= half_width * f_guess)
    w = 2 * np.pi * f[sel]
    H = -Y[sel] / U[sel] / w ** 2
    # H·a + jωH·b − R = ω²H, a = ω_n², b = 2ζω_n; R = Rr + j Ri
    M = np.column_stack([H, 1j * w * H, -np.ones_like(H), -1j * np.ones_like(H)])
    rhs = w ** 2 * H
    sol = np.linalg.lstsq(np.vstack([M.real, M.imag]), np.concatenate([rhs.real, rhs.imag]),
                          rcond=None)[0]
    wn = np.sqrt(sol[0])
    return float(wn / (2 * np.pi)), float(sol[1] / (2 * wn))
