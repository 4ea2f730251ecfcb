"""The general LTI family: a state-space model in real-block modal form.

    ẋ = A x + B u(t − τ),   y = C x + D u(t − τ) + y_off,

with A block-diagonal: ``nc`` complex pairs (2×2 blocks [[σ, ω_d], [−ω_d, σ]]), ``nr`` real
poles and ``ni`` explicit integrators (pole at 0). One state set is shared by every input
and output (a mode appears once, whatever the number of inputs); B and C are free, D
optional; τ_j is a per-input delay in whole samples (a structure attribute, chosen by
:mod:`rigd.ident.lti.order` before the fit, not a fitted parameter).

Parametrisation (well-conditioned and independent of units and rate):

* complex pair k: ``pk_lnf`` = ln(f_n / fs) and ``pk_zeta`` = ζ ∈ [1e-4, 0.99];
* real pole k: ``rk_lnf`` = ln(f_c / fs), the pole at −2π f_c (time constant 1/(2π f_c));
* B (``b<state>_<input>``), the free entries of C (``c<output>_<state>``), D
  (``d<output>_<input>``), the discrete innovation gain K (``k<state>_<output>``, used by the
  one-step predictor only), the initial state (``x0_<state>``) and the output offsets
  (``yoff_<output>``, re-estimated on a new record like x0).

Each block's scaling and rotation are fixed by one output row of C (``norm_rows``): C[r, s] = 1
for a real pole or an integrator, C[r, (s, s+1)] = (1, 0) for a pair, so no parameter is
redundant. Poles are bounded in the stable region relative to the record (frequencies from
a fraction of a period per estimation part to just below Nyquist for pairs; time constants
up to many record lengths for real poles); only the marked integrators sit at 0.

Simulation: :func:`rigd.ident.simulate.simulate_linear` (exact ZOH/FOH discretisation, the
compiled kernel); start values: :mod:`rigd.ident.lti.modal` (poles from a subspace model,
gains by linear least squares).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.ident.iddata import IdData
from rigd.ident.model import LinearPart, Model
from rigd.ident.readouts import linear_readouts
from rigd.ident.simulate import predict_linear, simulate_linear

#: damping ratio bounds of a complex pair
ZETA_MIN, ZETA_MAX = 1e-4, 0.99
#: highest natural frequency of a pair, and corner frequency of a real pole, per rate
F_MAX_PAIR, F_MAX_REAL = 0.95 * 0.5, 2.0


class StateSpaceModel(Model):
    """General LTI model in real-block modal form (module docstring).

    Parameters
    ----------
    inputs, outputs : list of str
        Channel names.
    fs : float
        Sample rate of the records it is fitted on, Hz (poles are parametrised relative to it).
    n_complex, n_real, n_int : int
        Complex pairs, real poles and explicit integrators; states = 2·n_complex + n_real +
        n_int.
    delays : sequence of int, optional
        Per-input delay in samples (default 0).
    hold : {"zoh", "foh"}
    feedthrough : bool
        Free D (else D = 0).
    output_offsets : bool
        Estimate a constant offset per output.
    norm_rows : sequence of int, optional
        Per block (pairs, then real poles, then integrators), the output row of C fixed to 1.
    """

    kind = "lti"

    def __init__(self, inputs, outputs, fs: float, n_complex: int = 0, n_real: int = 0,
                 n_int: int = 0, delays=None, hold: str = "foh", feedthrough: bool = False,
                 output_offsets: bool = True, norm_rows=None):
        if hold not in ("zoh", "foh"):
            raise ValueError(f"hold must be 'zoh' or 'foh', got {hold!r}")
        self.input_names, self.output_names = list(inputs), list(outputs)
        self.nu, self.ny = len(self.input_names), len(self.output_names)
        self.fs = float(fs)
        self.nc, self.nr, self.ni = int(n_complex), int(n_real), int(n_int)
        if min(self.nc, self.nr, self.ni) < 0:
            raise ValueError("block counts must be ≥ 0")
        self.nx = 2 * self.nc + self.nr + self.ni
        self.nblocks = self.nc + self.nr + self.ni
        self.delays = tuple(int(d) for d in (delays if delays is not None else [0] * self.nu))
        if len(self.delays) != self.nu or min(self.delays, default=0) < 0:
            raise ValueError(f"need {self.nu} non-negative delays, got {list(self.delays)}")
        self.hold = hold
        self.feedthrough = bool(feedthrough)
        self.output_offsets = bool(output_offsets)
        rows = list(norm_rows) if norm_rows is not None else [0] * self.nblocks
        if len(rows) != self.nblocks or any(not 0 <= r < self.ny for r in rows):
            raise ValueError(f"norm_rows needs {self.nblocks} output indices < {self.ny}")
        self.norm_rows = [int(r) for r in rows]
        self.effects = []
        self._n_est: int | None = None
        self._build_names()

    @property
    def n_integrators(self) -> int:
        return self.ni

    @property
    def carries(self) -> frozenset[str]:
        """``mode`` when the model has a complex pair (a mode's coordinate for an effect)."""
        return frozenset({"mode"}) if self.nc > 0 else frozenset()

    # --- layout ------------------------------------------------------------------------
    def block_states(self) -> list[tuple[str, int]]:
        """(type, first state) per block: ``pair``, ``real`` or ``int``."""
        out, s = [], 0
        for _ in range(self.nc):
            out.append(("pair", s))
            s += 2
        for t in ("real",) * self.nr + ("int",) * self.ni:
            out.append((t, s))
            s += 1
        return out

    def _fixed_c(self) -> dict[tuple[int, int], float]:
        fixed = {}
        for (t, s), r in zip(self.block_states(), self.norm_rows):
            fixed[(r, s)] = 1.0
            if t == "pair":
                fixed[(r, s + 1)] = 0.0
        return fixed

    def _build_names(self) -> None:
        names = [f"p{k + 1}_{w}" for k in range(self.nc) for w in ("lnf", "zeta")]
        names += [f"r{k + 1}_lnf" for k in range(self.nr)]
        g = {"poles": (0, len(names))}
        names += [f"b{s + 1}_{j + 1}" for s in range(self.nx) for j in range(self.nu)]
        g["b"] = (g["poles"][1], len(names))
        fixed = self._fixed_c()
        self._c_free = [(i, s) for i in range(self.ny) for s in range(self.nx)
                        if (i, s) not in fixed]
        names += [f"c{i + 1}_{s + 1}" for i, s in self._c_free]
        g["c"] = (g["b"][1], len(names))
        if self.feedthrough:
            names += [f"d{i + 1}_{j + 1}" for i in range(self.ny) for j in range(self.nu)]
        g["d"] = (g["c"][1], len(names))
        names += [f"k{s + 1}_{i + 1}" for s in range(self.nx) for i in range(self.ny)]
        g["k"] = (g["d"][1], len(names))
        # an integrator's initial state is a constant, the output offset's job when there is one
        ints = {st for t, st in self.block_states() if t == "int"}
        self._x0_states = [s for s in range(self.nx)
                           if not (self.output_offsets and s in ints)]
        names += [f"x0_{s + 1}" for s in self._x0_states]
        g["x0"] = (g["k"][1], len(names))
        if self.output_offsets:
            names += [f"yoff_{i + 1}" for i in range(self.ny)]
        g["yoff"] = (g["x0"][1], len(names))
        self.names = names
        self._g = g
        self.x0_index = list(range(*g["x0"]))
        self.offset_index = list(range(*g["yoff"]))
        self.noise_index = list(range(*g["k"]))

    def group_slices(self) -> dict[str, tuple[int, int]]:
        """name -> (start, stop) of each parameter group in theta."""
        return dict(self._g)

    # --- packing -----------------------------------------------------------------------
    def poles_c(self, theta) -> list[complex]:
        """Continuous pole per block (rad/s; the upper one of a pair)."""
        th = np.asarray(theta, float)
        out = []
        w0 = 2 * np.pi * self.fs
        for k in range(self.nc):
            # min/max: np.clip's value on a scalar (NaN kept) at a tenth of its cost
            wn, z = w0 * np.exp(th[2 * k]), min(max(float(th[2 * k + 1]), 0.0), 1.0)
            out.append(complex(-z * wn, wn * np.sqrt(1 - z * z)))
        for k in range(self.nr):
            out.append(complex(-w0 * np.exp(th[2 * self.nc + k]), 0.0))
        return out + [0j] * self.ni

    def pole_params(self, lam) -> np.ndarray:
        """Inverse of :meth:`poles_c` for the pairs and real poles (integrators have none)."""
        w0 = 2 * np.pi * self.fs
        out = []
        for v in lam[:self.nc]:
            wn = abs(v)
            out += [np.log(wn / w0), -v.real / wn]
        out += [np.log(abs(v.real) / w0) for v in lam[self.nc:self.nc + self.nr]]
        return np.array(out, float)

    def matrices(self, theta) -> dict[str, np.ndarray]:
        """A, B, C, D, K, x0 and yoff at ``theta``."""
        th = np.asarray(theta, float)
        A = np.zeros((self.nx, self.nx))
        for (t, s), lam in zip(self.block_states(), self.poles_c(th)):
            if t == "pair":
                A[s:s + 2, s:s + 2] = [[lam.real, lam.imag], [-lam.imag, lam.real]]
            else:
                A[s, s] = lam.real
        g = self._g
        B = th[slice(*g["b"])].reshape(self.nx, self.nu)
        C = np.zeros((self.ny, self.nx))
        for (i, s), v in self._fixed_c().items():
            C[i, s] = v
        for (i, s), v in zip(self._c_free, th[slice(*g["c"])]):
            C[i, s] = v
        D = (th[slice(*g["d"])].reshape(self.ny, self.nu) if self.feedthrough
             else np.zeros((self.ny, self.nu)))
        K = th[slice(*g["k"])].reshape(self.nx, self.ny)
        yoff = th[slice(*g["yoff"])] if self.output_offsets else np.zeros(self.ny)
        x0 = np.zeros(self.nx)
        x0[self._x0_states] = th[slice(*g["x0"])]
        return {"A": A, "B": B.copy(), "C": C, "D": D, "K": K.copy(),
                "x0": x0, "yoff": np.array(yoff, float)}

    def pack(self, lam, B, C, D=None, K=None, x0=None, yoff=None) -> np.ndarray:
        """theta from poles (one per block, as :meth:`poles_c`) and matrices (C in the
        normalised form: the fixed entries are not stored)."""
        th = np.zeros(len(self.names))
        g = self._g
        th[slice(*g["poles"])] = self.pole_params(list(lam))
        th[slice(*g["b"])] = np.asarray(B, float).ravel()
        C = np.asarray(C, float)
        th[slice(*g["c"])] = [C[i, s] for i, s in self._c_free]
        if self.feedthrough and D is not None:
            th[slice(*g["d"])] = np.asarray(D, float).ravel()
        if K is not None:
            th[slice(*g["k"])] = np.asarray(K, float).ravel()
        if x0 is not None:
            th[slice(*g["x0"])] = np.asarray(x0, float)[self._x0_states]
        if self.output_offsets and yoff is not None:
            th[slice(*g["yoff"])] = yoff
        return th

    # --- Model protocol ----------------------------------------------------------------
    def linear_part(self, theta) -> LinearPart:
        m = self.matrices(theta)
        s = self.block_states()
        ints = tuple(st for t, st in s if t == "int")
        return LinearPart(m["A"], m["B"], m["C"], m["D"], m["K"], self.delays, self.hold,
                          tuple(self.input_names), tuple(self.output_names), self.fs, ints)

    def continuous(self, theta):
        """(A, B, C, D, x0) of the continuous model (modal states; not the [p, ṗ] states of a
        mechanical model: :attr:`mechanical` is False). Read-outs of the poles (an
        integrator's slow real pole, rigd.effects.integrator) use it."""
        m = self.matrices(theta)
        return m["A"], m["B"], m["C"], m["D"], m["x0"]

    def set_record(self, n_est: int) -> None:
        """Bounds relative to the record: its estimation part has ``n_est`` samples."""
        self._n_est = int(n_est)

    def bounds(self):
        lo, hi = np.full(len(self.names), -np.inf), np.full(len(self.names), np.inf)
        n = self._n_est or 10 ** 6
        lo[0:2 * self.nc:2] = np.log(0.5 / n)         # half a period per estimation part
        hi[0:2 * self.nc:2] = np.log(F_MAX_PAIR)
        lo[1:2 * self.nc:2], hi[1:2 * self.nc:2] = ZETA_MIN, ZETA_MAX
        r = slice(2 * self.nc, 2 * self.nc + self.nr)
        lo[r] = np.log(1e-3 / (2 * np.pi * n))         # time constant ≤ 1000 record lengths
        hi[r] = np.log(F_MAX_REAL)
        return lo, hi

    def theta0(self, data: IdData) -> np.ndarray:
        from rigd.ident.lti.modal import initial_theta

        if self._n_est is None:
            self.set_record(data.n)
        return initial_theta(self, data)

    def scale(self, theta):
        th = np.asarray(theta, float)
        sc = np.ones(len(th))
        g = self._g
        sc[1:2 * self.nc:2] = 0.1
        for grp in ("b", "c", "d", "k", "x0", "yoff"):
            sl = slice(*g[grp])
            if sl.stop > sl.start:
                sc[sl] = max(float(np.max(np.abs(th[sl]))), 1e-300)
        sc[slice(*g["c"])] = np.maximum(sc[slice(*g["c"])], 1.0)  # relative to the fixed 1
        sc[slice(*g["k"])] = 1.0                                   # discrete gains, ~ 1
        return sc

    def simulate(self, theta, data):
        m = self.matrices(theta)
        y = simulate_linear(self.linear_part(theta), m["x0"], data.u, data.fs)
        return y + m["yoff"][None, :]

    def output_sensitivities(self, theta, data):
        """(indices, ∂ŷ/∂θ[indices] (k, n, ny)) of :meth:`simulate` for every parameter of
        the simulation (:func:`rigd.ident.lti.sensitivity.output_sensitivities`: exact for
        B, C, D, x0 and y_off, the sensitivity equations for the poles)."""
        from rigd.ident.lti.sensitivity import output_sensitivities

        return output_sensitivities(self, theta, data)

    def predict(self, theta, data):
        m = self.matrices(theta)
        y = predict_linear(self.linear_part(theta), m["x0"], data.u, data.y - m["yoff"],
                           data.fs)
        return None if y is None else y + m["yoff"][None, :]

    def output_offset(self, theta) -> np.ndarray | None:
        return self.matrices(theta)["yoff"] if self.output_offsets else None

    def ss(self, theta):
        return self.linear_part(theta).ss(self.kind)

    def resonances_hz(self, theta) -> list[float]:
        from rigd.ident.readouts import resonances_hz

        return resonances_hz(self.linear_part(theta))

    def readouts(self, theta) -> dict[str, Any]:
        out = linear_readouts(self.linear_part(theta))
        off = self.output_offset(theta)
        if off is not None:
            out["output_offset"] = off.tolist()
        return out

    def spec(self) -> dict[str, Any]:
        return {"kind": self.kind, "inputs": self.input_names, "outputs": self.output_names,
                "hold": self.hold, "fs_hz": self.fs,
                "blocks": {"complex": self.nc, "real": self.nr, "integrators": self.ni},
                "delays": list(self.delays), "feedthrough": self.feedthrough,
                "output_offsets": self.output_offsets, "norm_rows": list(self.norm_rows)}

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> StateSpaceModel:
        b = spec.get("blocks", {})
        return cls(spec["inputs"], spec["outputs"], float(spec["fs_hz"]),
                   int(b.get("complex", 0)), int(b.get("real", 0)), int(b.get("integrators", 0)),
                   spec.get("delays"), spec.get("hold", "foh"), bool(spec.get("feedthrough")),
                   bool(spec.get("output_offsets", True)), spec.get("norm_rows"))

    def describe(self) -> str:
        """``n states (a pairs, b real poles, c integrators)`` for print."""
        parts = [f"{self.nc} complex pair(s)", f"{self.nr} real pole(s)"]
        if self.ni:
            parts.append(f"{self.ni} integrator(s)")
        return f"{self.nx} states ({', '.join(parts)})"
