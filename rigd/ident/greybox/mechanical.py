"""Mechanical grey-box structures: the n-DOF model and the generic one of other rigs' records;
the rotor's bearing (Eqs. 5-7) and actuator (Eqs. 8-10) are built on it in
:mod:`rigd.ident.greybox.rotor`.

All three are the mass-normalised model of Eqs. 4-6,

    p̈ + D ṗ + K p = B u,    x = [p, ṗ],    p = C x + d,    ẋ = A x + 𝓑 u + 𝓑_d d,

with D ≜ 𝓜⁻¹(𝓓 − Ω𝓖), K ≜ 𝓜⁻¹𝓚, B ≜ 𝓜⁻¹𝓑_p (Eq. 6) and the disturbance gain 𝓑_d = [0; B_d].
They differ only in which entries are free:

* :func:`rigd.ident.greybox.rotor.bearing_structure` — 𝔐_b, all of D, K, B, B_d (2×2) and
  x0 (4): 20 parameters;
* :func:`rigd.ident.greybox.rotor.actuator_structure` — 𝔐_a, diagonal (decoupled
  second-order valves, Eq. 8): k_a, b_a, d_a, b_{d,a} per axis and x_{a0} (4): 12 parameters
  (Eq. 10);
* :func:`generic_structure` — any n outputs, nu inputs (records from other rigs), with a
  constant offset per output (``yoff_i``, y = p + y_off): a record from elsewhere rarely starts
  at rest at its own zero, so the output's zero is estimated with the model rather than taken
  from the record's first samples (which, on a slow process that starts away from equilibrium,
  leaves a bias no stable model can fit). Like x0, it is re-estimated on a record compared.
"""

from __future__ import annotations

import numpy as np

from rigd.ident.feedback import MechanicalFeedback
from rigd.ident.greybox.parallel import ParallelModes
from rigd.ident.iddata import IdData
from rigd.ident.initial import mechanical_initial
from rigd.ident.model import LinearPart, Model
from rigd.ident.readouts import linear_readouts
from rigd.ident.simulate import mechanical_abc, predict_mechanical, simulate_mechanical


class MechanicalStructure(Model):
    """p̈ + D ṗ + K p = B u with free entries given by boolean masks.

    Parameters
    ----------
    kind : str
        ``"bearing"``, ``"actuator"`` or ``"generic"`` (stored in model files).
    mask_K, mask_D, mask_Bd : ndarray (n, n) of bool
    mask_B : ndarray (n, nu) of bool
    prefix : str
        Parameter name prefix per group, e.g. ``""`` -> ``k_xy``, ``"a_"`` -> ``k_a_xx``.
    out_labels, in_labels : list of str
        Axis labels used in names (``x``, ``y`` or ``1``, ``2`` ...).
    input_names, output_names : list of str
        Channel names (for the StateSpace and reports).
    """
    #: states [p, ṗ] (p̈ + D ṗ + K p = B u) and a simulator that takes the state feedback
    #: of effects: what state-level effects act on
    carries = frozenset({"mechanical"})
    #: y = p (+ parallel modes) + y_off: the offsets' Jacobian columns are ones
    #: (rigd.ident.jacobian.additive_offsets)
    additive_offsets = True


    def __init__(self, kind, mask_K, mask_D, mask_B, mask_Bd, prefix="", out_labels=None,
                 in_labels=None, input_names=None, output_names=None, x0_name="x0_",
                 hold="zoh", output_offsets=False, extra_modes=0):
        self._args = (kind, mask_K, mask_D, mask_B, mask_Bd, prefix, out_labels, in_labels,
                      input_names, output_names, x0_name, hold, output_offsets)
        if hold not in ("zoh", "foh"):
            raise ValueError(f"hold must be 'zoh' or 'foh', got {hold!r}")
        self.hold = hold
        self.kind = kind
        self.mask_K = np.asarray(mask_K, bool)
        self.mask_D = np.asarray(mask_D, bool)
        self.mask_B = np.asarray(mask_B, bool)
        self.mask_Bd = np.asarray(mask_Bd, bool)
        self.n = self.mask_K.shape[0]
        self.nu = self.mask_B.shape[1]
        ol = out_labels or [str(i + 1) for i in range(self.n)]
        il = in_labels or [str(i + 1) for i in range(self.nu)]
        self.input_names = list(input_names or [f"u{i + 1}" for i in range(self.nu)])
        self.output_names = list(output_names or [f"y{i + 1}" for i in range(self.n)])
        names = []
        self._idx = {}
        for grp, mask, cl in (("d", self.mask_D, ol), ("k", self.mask_K, ol),
                              ("b", self.mask_B, il), ("bd", self.mask_Bd, ol)):
            ii, jj = np.nonzero(mask)
            self._idx[grp] = (len(names), ii, jj)
            names += [f"{grp}_{prefix}{ol[i]}{cl[j]}" if len(ol[i]) == 1 and len(cl[j]) == 1
                      else f"{grp}_{prefix}{ol[i]}_{cl[j]}" for i, j in zip(ii, jj)]
        self._x0 = len(names)
        names += [f"{x0_name}{i + 1}" for i in range(2 * self.n)]
        self._off = len(names)
        self.output_offsets = bool(output_offsets)
        if self.output_offsets:
            names += [f"yoff_{i + 1}" for i in range(self.n)]
        self.x0_index = list(range(self._x0, self._x0 + 2 * self.n))
        self.offset_index = list(range(self._off, len(names)))
        #: parameters of the mechanical part (the parallel modes' come after them)
        self.nb = len(names)
        #: the order search's parallel modes (rigd.ident.greybox.parallel), None without them
        self.parallel = (ParallelModes(extra_modes, self.input_names, self.output_names)
                         if extra_modes else None)
        if self.parallel is not None:
            names += self.parallel.names
            self.x0_index += self.parallel.x0_index(self.nb)
        self.names = names
        self.effects = []

    @property
    def m(self) -> int:
        """Number of parallel modes (beyond one per output)."""
        return 0 if self.parallel is None else self.parallel.m

    @property
    def n_parallel_modes(self) -> int:
        return self.m

    def with_modes(self, m: int) -> MechanicalStructure:
        """The same structure with ``m`` parallel modes (rigd.ident.greybox.parallel)."""
        return type(self)(*self._args, extra_modes=m)

    @property
    def velocity_index(self) -> list[int]:
        """Indices in θ of the initial velocities ṗ(0) of the mechanical part."""
        return list(range(self._x0 + self.n, self._x0 + 2 * self.n))

    def set_record(self, fs: float, n_est: int) -> None:
        """Bounds of the parallel modes relative to the record (rigd.ident.greybox.parallel)."""
        if self.parallel is not None:
            self.parallel.set_record(fs, n_est)

    def modes_of(self, theta) -> list[tuple[float, float, np.ndarray]]:
        """[(f_hz, zeta, g (nu, ny))] of the parallel modes."""
        return [] if self.parallel is None else self.parallel.modes_of(
            np.asarray(theta, float)[self.nb:])

    def parallel_output(self, theta, data) -> np.ndarray | None:
        """(n, ny) output of the parallel modes driven by the inputs of ``data`` plus their
        free response; None without either."""
        if self.parallel is None:
            return None
        return self.parallel.output(np.asarray(theta, float)[self.nb:], data.u, data.fs,
                                    self.hold)

    # --- packing -------------------------------------------------------------------
    def unpack(self, theta):
        """(K, D, B, Bd, x0) from theta."""
        theta = np.asarray(theta, float)
        n, nu = self.n, self.nu
        out = {}
        for grp, shape in (("d", (n, n)), ("k", (n, n)), ("b", (n, nu)), ("bd", (n, n))):
            s, ii, jj = self._idx[grp]
            M = np.zeros(shape)
            M[ii, jj] = theta[s:s + len(ii)]
            out[grp] = M
        return out["k"], out["d"], out["b"], out["bd"], theta[self._x0:self._x0 + 2 * n].copy()

    def pack(self, K, D, B, Bd=None, x0=None):
        """theta from matrices (entries outside the masks are ignored)."""
        n = self.n
        Bd = np.zeros((n, n)) if Bd is None else Bd
        x0 = np.zeros(2 * n) if x0 is None else x0
        theta = np.zeros(self.npar)
        for grp, M in (("d", D), ("k", K), ("b", B), ("bd", Bd)):
            s, ii, jj = self._idx[grp]
            theta[s:s + len(ii)] = np.asarray(M, float)[ii, jj]
        theta[self._x0:self._x0 + 2 * n] = x0
        return theta

    def group_slices(self):
        """name -> (start, stop) of each parameter group in theta."""
        out = {g: (s, s + len(ii)) for g, (s, ii, _) in self._idx.items()}
        out["x0"] = (self._x0, self._x0 + 2 * self.n)
        if self.output_offsets:
            out["yoff"] = (self._off, self._off + self.n)
        return out

    def output_offset(self, theta) -> np.ndarray | None:
        """The constant output offsets y_off (output units), None without them."""
        if not self.output_offsets:
            return None
        return np.asarray(theta, float)[self._off:self._off + self.n].copy()

    # --- Model API ---------------------------------------------------------------
    def theta0(self, data: IdData) -> np.ndarray:
        K, D, B = mechanical_initial(data.u, data.y, data.fs, self.mask_K, self.mask_D,
                                     self.mask_B, self.hold)
        x0 = np.zeros(2 * self.n)
        x0[:self.n] = data.y[0]
        th = self.pack(K, D, B, np.zeros((self.n, self.n)), x0)
        if self.parallel is not None:  # spread over the band; choose_order gives better starts
            th[self.nb:] = self.parallel.theta0(float(data.fs))
        return th

    def bounds(self):
        lo, hi = np.full(self.nb, -np.inf), np.full(self.nb, np.inf)
        if self.parallel is None:
            return lo, hi
        plo, phi = self.parallel.bounds()
        return np.concatenate([lo, plo]), np.concatenate([hi, phi])

    def scale(self, theta):
        K, D, B, Bd, x0 = self.unpack(theta)
        wmax = np.sqrt(max(np.max(np.abs(K)), 1e-6))
        sc = np.empty(self.npar)
        g = self.group_slices()
        sc[slice(*g["k"])] = max(np.max(np.abs(K)), 1e-6)
        sc[slice(*g["d"])] = max(np.max(np.abs(D)), 0.02 * wmax)
        sc[slice(*g["b"])] = max(np.max(np.abs(B)), 1e-300)  # any unit: no absolute floor
        sc[slice(*g["bd"])] = max(np.max(np.abs(Bd)), wmax)
        xs = max(np.max(np.abs(x0[:self.n])), 1e-9)
        sc[self._x0:self._x0 + self.n] = xs
        sc[self._x0 + self.n:self._x0 + 2 * self.n] = xs * wmax
        if self.output_offsets:
            sc[self._off:self._off + self.n] = xs
        if self.parallel is not None:  # gains at their size, free responses at the output's
            sc[self.nb:] = self.parallel.scale(np.asarray(theta, float)[self.nb:], xs)
        return sc

    def simulate(self, theta, data, feedback: MechanicalFeedback | None = None):
        """Simulated output (n, ny) from the inputs of ``data``; ``feedback``: the
        state-level effects' Lur'e feedback (rigd.ident.feedback, from rigd.effects.compose)."""
        K, D, B, Bd, x0 = self.unpack(theta)
        y = simulate_mechanical(K, D, B, x0, data.u, data.fs, feedback, self.hold)
        off = self.output_offset(theta)
        y = y if off is None else y + off
        par = self.parallel_output(theta, data)
        return y if par is None else y + par

    def predict(self, theta, data, feedback: MechanicalFeedback | None = None):
        """One-step prediction; the parallel modes' output is taken off the measurement and
        added back (they carry no disturbance)."""
        K, D, B, Bd, x0 = self.unpack(theta)
        par = self.parallel_output(theta, data)
        y = data.y if par is None else data.y - par
        yh = predict_mechanical(K, D, B, Bd, x0, data.u, y, data.fs, feedback, self.hold,
                                add=self.output_offset(theta))
        return yh if yh is None or par is None else yh + par

    def ss(self, theta):
        """Continuous StateSpace u -> y (states [p, ṗ], then the parallel modes');
        python-control."""
        import control

        if self.parallel is not None:
            A, B, C, D = self.full_abcd(theta)
            return control.ss(A, B, C, D, inputs=self.input_names, outputs=self.output_names,
                              name=self.kind)
        K, D, B, _, _ = self.unpack(theta)
        A, Bc, C = mechanical_abc(K, D, B)
        n = self.n
        return control.ss(A, Bc, C, np.zeros((n, self.nu)), inputs=self.input_names,
                          outputs=self.output_names,
                          states=[f"p{i + 1}" for i in range(n)] + [f"v{i + 1}" for i in range(n)],
                          name=self.kind)

    @property
    def ny(self) -> int:
        return self.n

    def continuous(self, theta):
        """(A, B, C, D, x0) of the continuous model (for state-level effects, rigd.effects)."""
        K, D, B, _, x0 = self.unpack(theta)
        A, Bc, C = mechanical_abc(K, D, B)
        return A, Bc, C, np.zeros((self.n, self.nu)), x0

    def full_abcd(self, theta):
        """(A, B, C, D) of the whole linear model: [p, ṗ], then the parallel modes."""
        A0, B0, C0, D0, _ = self.continuous(theta)
        if self.parallel is None:
            return A0, B0, C0, D0
        from scipy.linalg import block_diag

        As, Bs, Cs = self.parallel.blocks(np.asarray(theta, float)[self.nb:])
        return block_diag(A0, *As), np.vstack([B0] + Bs), np.hstack([C0] + Cs), D0

    def linear_part(self, theta) -> LinearPart:
        """The model's linear dynamics (states [p, ṗ], then the parallel modes'; no delay,
        no feedthrough)."""
        A, Bc, C, Dm = self.full_abcd(theta)
        return LinearPart(A, Bc, C, Dm, None, (0,) * self.nu, self.hold,
                          tuple(self.input_names), tuple(self.output_names))

    def resonances_hz(self, theta) -> list[float]:
        """Natural frequencies (Hz) of every mode, mechanical and parallel."""
        lam = np.linalg.eigvals(self.full_abcd(theta)[0])
        return sorted({round(float(abs(v) / (2 * np.pi)), 6) for v in lam if v.imag > 1e-9})

    def modes(self, theta):
        """Modes of A: list of dicts with f_n (Hz), zeta (-), or real poles (rad/s)
        (:func:`rigd.ident.readouts.modes`)."""
        from rigd.ident.readouts import modes

        return modes(self.linear_part(theta))

    def readouts(self, theta):
        out = linear_readouts(self.linear_part(theta))
        off = self.output_offset(theta)
        if off is not None:
            out["output_offset"] = off.tolist()
        return out

    def spec(self):
        d = {"kind": self.kind, "inputs": self.input_names, "outputs": self.output_names,
             "hold": self.hold}
        if self.kind == "generic":
            d["n"] = self.n
            d["nu"] = self.nu
            d["output_offsets"] = self.output_offsets
        if self.parallel is not None:
            d["extra_modes"] = self.parallel.m
        return d


def generic_structure(inputs: list[str], outputs: list[str], hold: str = "zoh",
                      output_offsets: bool = True) -> MechanicalStructure:
    """n-DOF M p̈ + D ṗ + K p = B u (mass-normalised), y = p + y_off, for records from
    other rigs.

    The inputs of other rigs are usually measured, smooth signals: ``rigd identify`` takes
    them as linear between samples (``hold="foh"``,
    :data:`rigd.ident.greybox.submodels.DEFAULT_HOLD`). ``output_offsets``: estimate the
    outputs' zero with the model (module docstring); False only for model files written
    before it existed.
    """
    n, nu = len(outputs), len(inputs)
    return MechanicalStructure("generic", np.ones((n, n), bool), np.ones((n, n), bool),
                               np.ones((n, nu), bool), np.ones((n, n), bool), "", None, None,
                               inputs, outputs, hold=hold, output_offsets=output_offsets)
