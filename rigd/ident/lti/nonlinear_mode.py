"""One mode of a modal LTI model made nonlinear: the ``mode`` site of the effects.

The general LTI family (:class:`rigd.ident.lti.statespace.StateSpaceModel`) keeps each
complex pair k as a 2×2 block ẋ_k = A_k x_k + B_k u. Its *modal coordinate* q_k is the one
coordinate of that block whose second derivative the input drives directly (companion form):
with b the block's column of B for the driving input (the first input),

    q = w·x_k,   q̇ = (w A_k)·x_k,   w·b = 0,   (w A_k)·b = 1,

so that q̈ + 2ζω q̇ + ω² q = u (the input in its own unit, e.g. N: q is the modal
displacement per unit modal mass and gain, ω² q a force in the input's unit). A nonlinear
restoring force φ(q, q̇; θe) fed back into that mode only,

    q̈ + 2ζω q̇ + ω² q + φ = u,    i.e.  ẋ_k = A_k x_k + B_k u − b φ,

is what structural dynamicists call a nonlinear mode (a joint in one mode's load path). The
other blocks stay linear: the output is the base's linear simulation plus C_k (x_k − x_k^lin),
the difference of the mode's nonlinear and linear trajectories (minus the force's direct share
of each output, for a sensor of the mode's acceleration), both integrated by the same RK4
kernel on sub-steps (the input held or interpolated as the base's ZOH/FOH hold), so the
kernel's own discretisation error cancels in the difference.

Laws φ (:data:`LAWS`; ``p`` the law's parameters, in the input's unit):

* ``cubic``: φ = p0 q³;
* ``iwan``: a parallel set of Jenkins elements (spring p0 in series with a Coulomb slider of
  slip force p[1 + e]; state = the slider positions), minus their stuck stiffness
  (p0 · elements · q): the base's ω is the stuck mode, the joint softens and damps it as the
  sliders slip (elastic–perfectly-plastic hysteresis per element, return mapping at the end of
  each sub-step);
* ``clearance``: a dead-zone spring, φ = p0 (q − p1 sign q) for |q| > p1 (gap p1), else 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rigd.ident.simulate import shift_inputs

__all__ = ["LAWS", "modal_frame", "mode_states", "simulate_nonlinear_mode", "mode_force"]

#: law name -> kernel code
LAWS = {"cubic": 0, "iwan": 1, "clearance": 2}
#: largest ω·h of the RK4 sub-steps (rad): sub-steps per sample follow from it
MAX_WH = 0.2


@njit(cache=True, inline="always")
def _phi(q, z, law, p):  # pragma: no cover - compiled
    """The restoring force of law ``law`` at q from the committed slider positions z."""
    if law == 0:
        return p[0] * q * q * q
    if law == 2:
        if q > p[1]:
            return p[0] * (q - p[1])
        if q < -p[1]:
            return p[0] * (q + p[1])
        return 0.0
    g = 0.0
    for e in range(z.shape[0]):
        fe = p[0] * (q - z[e])
        fs = p[1 + e]
        if fe > fs:
            fe = fs
        elif fe < -fs:
            fe = -fs
        g += fe - p[0] * q
    return g


@njit(cache=True, inline="always")
def _commit(q, z, p):  # pragma: no cover - compiled
    """Return mapping of the sliders at q (Iwan law)."""
    for e in range(z.shape[0]):
        fe = p[0] * (q - z[e])
        fs = p[1 + e]
        if fe > fs:
            z[e] = q - fs / p[0]
        elif fe < -fs:
            z[e] = q + fs / p[0]


@njit(cache=True)
def mode_kernel(A, bu, b, w, wa, x0, law, p, nel, sub, dt, foh):  # pragma: no cover
    """RK4 of one 2-state block with and without φ fed back along ``b``.

    Parameters
    ----------
    A : (2, 2) continuous block; bu : (n, 2) the block's drive B_k u at the samples;
    b : (2,) direction of φ; w, wa : (2,) the coordinate rows (q = w·x, q̇ = wa·x);
    x0 : (2,) initial state; law, p : the law (module docstring); nel : sliders (Iwan);
    sub : sub-steps per sample; dt : sample time, s; foh : interpolate the drive linearly.

    Returns
    -------
    (xn, xl, fn) : (n, 2), (n, 2), (n,)
        The nonlinear and the linear trajectories at the samples and φ at the samples.
    """
    n = bu.shape[0]
    xn = np.empty((n, 2))
    xl = np.empty((n, 2))
    fn = np.empty(n)
    z = np.zeros(max(nel, 1))
    h = dt / sub
    a = np.array([x0[0], x0[1]])
    c = np.array([x0[0], x0[1]])
    ka = np.empty((4, 2))
    kc = np.empty((4, 2))
    for i in range(n):
        xn[i, 0], xn[i, 1] = a[0], a[1]
        xl[i, 0], xl[i, 1] = c[0], c[1]
        fn[i] = _phi(w[0] * a[0] + w[1] * a[1], z, law, p)
        j = i + 1 if i + 1 < n else i
        for t in range(sub):
            for st in range(4):
                cw = 0.0 if st == 0 else (0.5 if st < 3 else 1.0)
                tau = (t + cw) / sub
                fr = tau if foh else 0.0
                d0 = bu[i, 0] + fr * (bu[j, 0] - bu[i, 0])
                d1 = bu[i, 1] + fr * (bu[j, 1] - bu[i, 1])
                a0 = a[0] + (cw * h * ka[st - 1, 0] if st else 0.0)
                a1 = a[1] + (cw * h * ka[st - 1, 1] if st else 0.0)
                c0 = c[0] + (cw * h * kc[st - 1, 0] if st else 0.0)
                c1 = c[1] + (cw * h * kc[st - 1, 1] if st else 0.0)
                f = _phi(w[0] * a0 + w[1] * a1, z, law, p)
                ka[st, 0] = A[0, 0] * a0 + A[0, 1] * a1 + d0 - b[0] * f
                ka[st, 1] = A[1, 0] * a0 + A[1, 1] * a1 + d1 - b[1] * f
                kc[st, 0] = A[0, 0] * c0 + A[0, 1] * c1 + d0
                kc[st, 1] = A[1, 0] * c0 + A[1, 1] * c1 + d1
            for r in range(2):
                a[r] += h / 6.0 * (ka[0, r] + 2.0 * ka[1, r] + 2.0 * ka[2, r] + ka[3, r])
                c[r] += h / 6.0 * (kc[0, r] + 2.0 * kc[1, r] + 2.0 * kc[2, r] + kc[3, r])
            if law == 1:
                _commit(w[0] * a[0] + w[1] * a[1], z, p)
        if not (math.isfinite(a[0]) and math.isfinite(a[1])):
            for k in range(i + 1, n):
                xn[k, 0], xn[k, 1], fn[k] = np.nan, np.nan, np.nan
                xl[k, 0], xl[k, 1] = c[0], c[1]
            break
    return xn, xl, fn


def modal_frame(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(w, wa): the rows giving the modal coordinate q = w·x and its velocity q̇ = wa·x of
    the 2×2 block ``A`` driven along ``b`` (module docstring; wa = w A).

    Raises
    ------
    ValueError
        The input does not drive the block (its controllability matrix is singular).
    """
    A, b = np.asarray(A, float), np.asarray(b, float)
    Wc = np.column_stack([b, A @ b])
    if abs(np.linalg.det(Wc)) <= 1e-12 * max(np.linalg.norm(Wc) ** 2, 1e-300):
        raise ValueError("the input does not drive this mode: it has no modal coordinate")
    w = np.linalg.solve(Wc.T, np.array([0.0, 1.0]))
    return w, w @ A


def mode_states(base, mode: int) -> int:
    """First state of the ``mode``-th complex pair (1-based) of ``base``; ValueError when
    it has no such pair."""
    pairs = [s for t, s in base.block_states() if t == "pair"]
    k = int(round(mode))
    if not 1 <= k <= len(pairs):
        raise ValueError(f"mode {k} asked of a model with {len(pairs)} mode(s)")
    return pairs[k - 1]


def mode_hz(base, theta_b, mode: int) -> tuple[float, float]:
    """(natural frequency Hz, damping ratio) of the ``mode``-th pair at ``theta_b``."""
    lam = [v for v in base.poles_c(theta_b) if v.imag > 0][int(round(mode)) - 1]
    return abs(lam) / (2 * np.pi), -lam.real / abs(lam)


def _parts(base, theta_b, data, mode: int):
    """(s, A_k, B_k u, b, w, wa, x0_k, C_k, m) of the mode at ``theta_b`` on ``data``."""
    m = base.matrices(theta_b)
    s = mode_states(base, mode)
    Ak = m["A"][s:s + 2, s:s + 2]
    u = shift_inputs(np.ascontiguousarray(np.asarray(data.u, float)), base.delays)
    Bk = m["B"][s:s + 2]
    w, wa = modal_frame(Ak, Bk[:, 0])
    return (s, Ak, np.ascontiguousarray(u @ Bk.T), np.ascontiguousarray(Bk[:, 0]), w, wa,
            np.ascontiguousarray(m["x0"][s:s + 2]), m["C"][:, s:s + 2])


def substeps(w_max: float, fs: float) -> int:
    """RK4 sub-steps per sample for a fastest angular frequency ``w_max`` (rad/s)."""
    return int(min(64, max(2, math.ceil(w_max / fs / MAX_WH))))


def simulate_nonlinear_mode(base, theta_b, data, mode: int, law: str, p: np.ndarray,
                            nel: int = 0, w_extra: float = 0.0,
                            direct: np.ndarray | None = None) -> np.ndarray:
    """Output (n, ny) of ``base`` at ``theta_b`` on ``data`` with the ``mode``-th pair's
    coordinate fed back through ``law`` with parameters ``p`` (module docstring);
    ``w_extra``: the law's largest added stiffness (rad²/s²) for the sub-step count;
    ``direct`` (ny,): the force's direct share in each output, y −= direct·φ (a sensor of
    the mode's acceleration q̈ sees the force at once: its share of the base's D)."""
    y = np.asarray(base.simulate(theta_b, data), float)
    dx, fn, Ck = mode_departure(base, theta_b, data, mode, law, p, nel, w_extra)
    y = y + dx @ Ck.T
    if direct is not None:
        y = y - fn[:, None] * np.asarray(direct, float)[None, :]
    return y


def mode_departure(base, theta_b, data, mode: int, law: str, p: np.ndarray, nel: int = 0,
                   w_extra: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x_k − x_k^lin (n, 2), φ (n,), C_k (ny, 2)): how far the law moves the ``mode``-th
    pair's states from the linear ones, the law's force and the pair's output columns
    (:func:`simulate_nonlinear_mode` adds ``(x_k − x_k^lin) C_kᵀ`` to the base's output)."""
    s, Ak, bu, b, w, wa, x0, Ck = _parts(base, theta_b, data, mode)
    wn = float(np.sqrt(abs(np.linalg.det(Ak)) + max(w_extra, 0.0)))
    fs = float(data.fs)
    xn, xl, fn = mode_kernel(np.ascontiguousarray(Ak), bu, b, w, wa, x0, LAWS[law],
                             np.ascontiguousarray(p, dtype=float), int(nel),
                             substeps(wn, fs), 1.0 / fs, base.hold == "foh")
    return xn - xl, fn, Ck


def mode_force(base, theta_b, data, mode: int) -> dict[str, np.ndarray]:
    """The base's linear modal coordinate of the ``mode``-th pair on ``data``: ``q``, ``v``
    (q̇) (n,), ``C`` (ny, 2) its output columns (``Cq`` the same on [q, q̇]), ``A``, ``b``
    (the block and the direction a force enters), ``w2`` (ω², rad²/s²), for signatures:
    the output change of a force f into the mode is C·(response of ẋ = A x − b f)."""
    s, Ak, bu, b, w, wa, x0, Ck = _parts(base, theta_b, data, mode)
    wn = float(np.sqrt(abs(np.linalg.det(Ak))))
    _, xl, _ = mode_kernel(np.ascontiguousarray(Ak), bu, b, w, wa, x0, 0, np.zeros(1), 0,
                           substeps(wn, float(data.fs)), 1.0 / float(data.fs),
                           base.hold == "foh")
    T = np.linalg.inv(np.vstack([w, wa]))                 # x = T [q, q̇]
    return {"q": xl @ w, "v": xl @ wa, "C": Ck, "A": Ak, "b": b, "w2": wn ** 2,
            "Cq": Ck @ T}


def force_response(info: dict, f: np.ndarray, fs: float) -> np.ndarray:
    """Output change (n, ny) of a force ``f`` (n,) fed back (subtracted) into the mode of
    ``info`` (:func:`mode_force`), ZOH-discretised: a second-order filter per output."""
    from scipy.signal import lfilter, ss2tf

    from rigd.lti import zoh

    Ad, Bd = zoh(info["A"], -info["b"][:, None], 1.0 / fs)
    out = np.empty((len(f), info["C"].shape[0]))
    for i in range(info["C"].shape[0]):
        num, den = ss2tf(Ad, Bd, info["C"][i:i + 1], np.zeros((1, 1)))
        out[:, i] = lfilter(num[0], den, f)
    return out
