"""The low-order process family (like MATLAB's ``idproc``) for slow process and thermal records.

Each input–output pair (i, j) is its own low-order transfer function, the inputs delayed by
the per-input delay τ_j (samples):

* ``P1D``:  K_ij / (1 + T1_ij s)
* ``P2D``:  K_ij / ((1 + T1_ij s)(1 + T2_ij s))
* ``P1DI``: K_ij / (s (1 + T1_ij s))   (an integrator: K_ij is the slope per unit input, 1/s)

plus an initial state per pair's states and a constant offset per output. Parameters:
``K<i>_<j>`` (output units per input unit; per second with the integrator) and
``lnT1_<i>_<j>`` = ln(T1·fs) (T1 in seconds; ``lnT2`` likewise), so nothing depends on the
units or the rate. It is a :class:`rigd.ident.model.Model`: its :meth:`linear_part` is the
block-diagonal state-space form (one block per pair), simulated by the one linear kernel.

:func:`process_candidates` fits every kind on a record (time constants from a grid, gains,
initial states and offsets by linear least squares) for :mod:`rigd.ident.lti.order`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rigd.ident.lti.candidates import Candidate, score
from rigd.ident.model import LinearPart, Model
from rigd.ident.readouts import linear_readouts
from rigd.ident.simulate import simulate_linear

KINDS = {"P1D": (1, False), "P2D": (2, False), "P1DI": (1, True)}


class ProcessModel(Model):
    """Per-pair low-order process model (module docstring).

    Parameters
    ----------
    inputs, outputs : list of str
    fs : float
        Sample rate, Hz.
    kind : {"P1D", "P2D", "P1DI"}
    delays : sequence of int, optional
        Per-input delay, samples.
    hold : {"zoh", "foh"}
    """

    def __init__(self, inputs, outputs, fs: float, kind: str = "P1D", delays=None,
                 hold: str = "foh"):
        if kind not in KINDS:
            raise ValueError(f"unknown process kind {kind!r} (known: {', '.join(KINDS)})")
        self.kind_name = kind
        self.kind = "process"
        self.input_names, self.output_names = list(inputs), list(outputs)
        self.nu, self.ny = len(self.input_names), len(self.output_names)
        self.fs, self.hold = float(fs), hold
        self.delays = tuple(int(d) for d in (delays if delays is not None else [0] * self.nu))
        self.npoles, self.integrator = KINDS[kind]
        self.per = self.npoles + (1 if self.integrator else 0)   # states per pair
        self.pairs = [(i, j) for i in range(self.ny) for j in range(self.nu)]
        self.nx = self.per * len(self.pairs)
        names = [f"K{i + 1}_{j + 1}" for i, j in self.pairs]
        for p in range(self.npoles):
            names += [f"lnT{p + 1}_{i + 1}_{j + 1}" for i, j in self.pairs]
        self._x0 = len(names)
        # an integrator's initial state is a constant: the output offset's job
        self._x0_states = [s for s in range(self.nx)
                           if not (self.integrator and s % self.per == self.per - 1)]
        names += [f"x0_{s + 1}" for s in self._x0_states]
        self._off = len(names)
        names += [f"yoff_{i + 1}" for i in range(self.ny)]
        self.names = names
        self.x0_index = list(range(self._x0, self._off))
        self.offset_index = list(range(self._off, len(names)))
        self.noise_index = []
        self.effects = []
        self._n_est: int | None = None

    @property
    def npairs(self) -> int:
        return len(self.pairs)

    def set_record(self, n_est: int) -> None:
        self._n_est = int(n_est)

    def bounds(self):
        lo, hi = np.full(len(self.names), -np.inf), np.full(len(self.names), np.inf)
        n = self._n_est or 10 ** 6
        s = slice(self.npairs, self.npairs * (1 + self.npoles))
        lo[s], hi[s] = np.log(0.05), np.log(1e3 * n)   # T from 1/20 sample to 1000 records
        return lo, hi

    def scale(self, theta):
        th = np.asarray(theta, float)
        sc = np.ones(len(th))
        for sl in (slice(0, self.npairs), slice(self._x0, self._off), slice(self._off, None)):
            if sl.start != sl.stop and th[sl].size:
                sc[sl] = max(float(np.max(np.abs(th[sl]))), 1e-300)
        return sc

    def matrices(self, theta) -> dict[str, np.ndarray]:
        th = np.asarray(theta, float)
        A = np.zeros((self.nx, self.nx))
        B = np.zeros((self.nx, self.nu))
        C = np.zeros((self.ny, self.nx))
        for q, (i, j) in enumerate(self.pairs):
            s = q * self.per
            K = th[q]
            T = [np.exp(th[self.npairs * (1 + p) + q]) / self.fs for p in range(self.npoles)]
            A[s, s], B[s, j] = -1.0 / T[0], K / T[0]
            if self.npoles == 2:
                A[s + 1, s], A[s + 1, s + 1] = 1.0 / T[1], -1.0 / T[1]
            if self.integrator:
                A[s + 1, s] = 1.0
            C[i, s + self.per - 1] = 1.0
        x0 = np.zeros(self.nx)
        x0[self._x0_states] = th[self._x0:self._off]
        return {"A": A, "B": B, "C": C, "x0": x0, "yoff": th[self._off:].copy()}

    def linear_part(self, theta) -> LinearPart:
        m = self.matrices(theta)
        ints = tuple(q * self.per + 1 for q in range(self.npairs)) if self.integrator else ()
        return LinearPart(m["A"], m["B"], m["C"], np.zeros((self.ny, self.nu)), None,
                          self.delays, self.hold, tuple(self.input_names),
                          tuple(self.output_names), self.fs, ints)

    def simulate(self, theta, data):
        m = self.matrices(theta)
        return simulate_linear(self.linear_part(theta), m["x0"], data.u,
                               data.fs) + m["yoff"][None, :]

    def output_offset(self, theta):
        return np.asarray(theta, float)[self._off:].copy()

    def ss(self, theta):
        return self.linear_part(theta).ss(self.kind)

    def theta0(self, data) -> np.ndarray:
        self.set_record(self._n_est or data.n)
        return fit_by_grid(self, data)[0]

    def readouts(self, theta) -> dict[str, Any]:
        out = linear_readouts(self.linear_part(theta))
        th = np.asarray(theta, float)
        out["process"] = {
            f"{self.output_names[i]}<-{self.input_names[j]}": {
                ("K_per_s" if self.integrator else "K"): float(th[q]),
                **{f"T{p + 1}_s": float(np.exp(th[self.npairs * (1 + p) + q]) / self.fs)
                   for p in range(self.npoles)},
                "Td_s": self.delays[j] / self.fs}
            for q, (i, j) in enumerate(self.pairs)}
        out["output_offset"] = self.output_offset(theta).tolist()
        return out

    def spec(self) -> dict[str, Any]:
        return {"kind": self.kind, "process": self.kind_name, "inputs": self.input_names,
                "outputs": self.output_names, "hold": self.hold, "fs_hz": self.fs,
                "delays": list(self.delays), "output_offsets": True}

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> ProcessModel:
        return cls(spec["inputs"], spec["outputs"], float(spec["fs_hz"]),
                   spec.get("process", "P1D"), spec.get("delays"), spec.get("hold", "foh"))

    @property
    def n_integrators(self) -> int:
        return int(self.integrator)

    def describe(self) -> str:
        return f"{self.kind_name} per input-output pair ({self.nx} states)"


def affine_lstsq(model, theta, idx, data) -> np.ndarray:
    """theta with the entries ``idx`` (in which the simulated output is affine) set by least
    squares on ``data`` (outputs weighted by 1/std): one simulation per entry."""
    th = np.array(theta, float)
    th[idx] = 0.0
    y0 = np.asarray(model.simulate(th, data))
    w = 1.0 / np.maximum(np.std(data.y, axis=0), 1e-300)
    cols = []
    for i in idx:
        t1 = th.copy()
        t1[i] = 1.0
        cols.append(((np.asarray(model.simulate(t1, data)) - y0) * w).ravel())
    M = np.column_stack(cols)
    nrm = np.linalg.norm(M, axis=0)
    nrm[nrm == 0] = 1.0
    th[idx] = np.linalg.lstsq(M / nrm, ((data.y - y0) * w).ravel(), rcond=1e-12)[0] / nrm
    return th


def fit_by_grid(model: ProcessModel, data) -> tuple[np.ndarray, float]:
    """Time constants from a log grid (the same for every pair), the rest by
    :func:`affine_lstsq`; returns (theta, weighted SSE)."""
    n = data.n
    grid = np.log(np.geomspace(1.0, max(2.0, n / 2), 10))
    lin = list(range(model.npairs)) + model.x0_index + model.offset_index
    w = 1.0 / np.maximum(np.std(data.y, axis=0), 1e-300)
    best, best_sse = None, np.inf
    ratios = (0.2, 0.5) if model.npoles == 2 else (None,)
    for g in grid:
        for r in ratios:
            th = np.zeros(len(model.names))
            th[model.npairs:2 * model.npairs] = g
            if r is not None:
                th[2 * model.npairs:3 * model.npairs] = g + np.log(r)
            try:
                th = affine_lstsq(model, th, lin, data)
            except np.linalg.LinAlgError:
                continue
            yh = model.simulate(th, data)
            sse = float(np.sum(((data.y - yh) * w) ** 2))
            if np.isfinite(sse) and sse < best_sse:
                best, best_sse = th, sse
    if best is None:
        best = np.zeros(len(model.names))
    return best, best_sse


def process_candidates(data, d_est, est, val, delays, hold, skip: int = 0) -> list:
    """One candidate per process kind (for :func:`rigd.ident.lti.order.choose_base`);
    ``skip``: samples left out of the criterion (:func:`~rigd.ident.lti.candidates.settle`)."""
    out = []
    for kind in KINDS:
        m = ProcessModel(d_est.input_names, d_est.output_names, data.fs, kind, delays, hold)
        m.set_record(d_est.n)
        th, _ = fit_by_grid(m, d_est)
        b, fe, fv = score(m, th, data, est, val, skip)
        out.append(Candidate("process", m.nx, m, th, b, fe, fv, len(m.names), skip))
    return out
