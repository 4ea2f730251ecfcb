"""Parallel modes of the mechanical n-DOF model: the order search's modes beyond one per output.

A record from another rig may carry more modes than it has outputs (a flexible structure
measured at one point). The generic mechanical structure (one DOF per output,
:func:`rigd.ident.greybox.mechanical.generic_structure`) then takes ``m`` parallel modes, each
ω²/(s² + 2ζω s + ω²) from every input to every output with its own gains, and their free
response from initial values. Per mode k (named from 2, the base's being 1):

* ``modeK_f_hz`` (natural frequency, Hz), ``modeK_zeta`` (damping ratio);
* ``modeK_g_<in>_<out>`` (gain of input ``in`` into output ``out``);
* ``modeK_x0c_<out>``, ``modeK_x0s_<out>`` (free response e^(−ζωt)(a cos ω_d t + b sin ω_d t)).

:class:`ParallelModes` holds the parametrisation (names, start values, bounds relative to the
record, step sizes) and what the structure adds: the output (:func:`rigd.ident.simulate.
parallel_modes` plus the free response) and the blocks of the whole linear part. The
structure (rigd.ident.greybox.mechanical.MechanicalStructure with ``extra_modes``) passes it the
modes' slice of θ; state-level effects act on the mechanical part's [p, ṗ] only.
"""

from __future__ import annotations

import numpy as np

from rigd.ident.simulate import ExtraMode, parallel_modes

__all__ = ["ParallelModes"]


class ParallelModes:
    """``m`` parallel modes from ``nu`` inputs to ``ny`` outputs (module docstring).

    Parameters
    ----------
    m : int
        Number of modes.
    input_names, output_names : list of str
        Channel names (in the parameter names).
    """

    def __init__(self, m: int, input_names: list[str], output_names: list[str]):
        self.m, self.nu, self.ny = int(m), len(input_names), len(output_names)
        names = []
        for k in range(self.m):
            pre = f"mode{k + 2}_"
            names += [pre + "f_hz", pre + "zeta"]
            names += [f"{pre}g_{a}_{b}" for a in input_names for b in output_names]
            names += [f"{pre}x0{c}_{b}" for c in "cs" for b in output_names]
        self.names = names
        self.per = 2 + self.nu * self.ny + 2 * self.ny
        #: record scale of the bounds (:meth:`set_record`): rate and lowest frequency, Hz
        self.fs: float | None = None
        self.fmin = 0.0

    def x0_index(self, offset: int) -> list[int]:
        """Indices in θ (the modes' slice starting at ``offset``) of the free-response
        amplitudes: initial states, re-estimated on a new record."""
        out = []
        for k in range(self.m):
            s = offset + k * self.per + 2 + self.nu * self.ny
            out += list(range(s, s + 2 * self.ny))
        return out

    def set_record(self, fs: float, n_est: int) -> None:
        """Bounds relative to the record: f in [2 periods per estimation part, 0.95 Nyquist]."""
        self.fs = float(fs)
        self.fmin = 2.0 * float(fs) / max(int(n_est), 1)

    # --- parameters -------------------------------------------------------------------
    def modes_of(self, th) -> list[tuple[float, float, np.ndarray]]:
        """[(f_hz, zeta, g (nu, ny))] from the modes' slice ``th`` of θ."""
        th = np.asarray(th, float)
        ng = self.nu * self.ny
        out = []
        for k in range(self.m):
            t = th[k * self.per:(k + 1) * self.per]
            out.append((float(t[0]), float(t[1]), t[2:2 + ng].reshape(self.nu, self.ny)))
        return out

    def theta0(self, fs: float) -> np.ndarray:
        """Start values spread over the band (the order search gives better ones)."""
        self.fs = float(fs)
        out = []
        for k in range(self.m):
            out += ([float(fs) * 0.05 * (k + 2), 0.05] + [0.0] * (self.nu * self.ny)
                    + [0.0] * (2 * self.ny))
        return np.asarray(out, float)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        fmax = 0.95 * self.fs / 2 if self.fs else np.inf
        lo, hi = [], []
        for _ in range(self.m):
            lo += [self.fmin, 1e-4] + [-np.inf] * (self.nu * self.ny + 2 * self.ny)
            hi += [fmax, 0.95] + [np.inf] * (self.nu * self.ny + 2 * self.ny)
        return np.asarray(lo, float), np.asarray(hi, float)

    def scale(self, th, ys: float) -> np.ndarray:
        """Typical sizes; ``ys`` the output scale of the mechanical part."""
        se = []
        for f, _z, g in self.modes_of(th):
            gs = max(float(np.max(np.abs(g))), 1e-300) if g.size else 1.0
            se += [max(abs(f), 1e-9), 0.05] + [gs] * g.size + [ys] * (2 * self.ny)
        return np.asarray(se, float)

    # --- what the structure adds ------------------------------------------------------
    def free_response(self, th, n: int, fs: float) -> np.ndarray | None:
        """(n, ny) free response of the modes from their initial values (None: all zero)."""
        th = np.asarray(th, float)
        t = np.arange(n) / float(fs)
        out = None
        ng = self.nu * self.ny
        for k in range(self.m):
            blk = th[k * self.per:(k + 1) * self.per]
            f, z = blk[0], min(max(blk[1], 0.0), 0.999)
            ab = blk[2 + ng:].reshape(2, self.ny)
            if not np.any(ab):
                continue
            w = 2 * np.pi * f
            wd = w * np.sqrt(1 - z * z)
            env = np.exp(-z * w * t)
            y = (env * np.cos(wd * t))[:, None] * ab[0] + (env * np.sin(wd * t))[:, None] * ab[1]
            out = y if out is None else out + y
        return out

    def output(self, th, u: np.ndarray, fs: float, hold: str) -> np.ndarray | None:
        """(n, ny) output of the modes driven by ``u`` (n, nu) with the input ``hold``, plus
        their free response; None without either."""
        modes = []
        for f, z, g in self.modes_of(th):
            w = 2 * np.pi * f
            for j in range(self.nu):
                b = np.zeros(self.nu)
                b[j] = w * w
                modes.append(ExtraMode(w, z, b, g[j].copy()))
        out = parallel_modes(modes, np.ascontiguousarray(u, dtype=float), 1.0 / float(fs), hold)
        free = self.free_response(th, u.shape[0], fs)
        if free is not None:
            out = free if out is None else out + free
        return out

    def blocks(self, th) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
        """(A, B, C) blocks of the modes in the whole linear part: a minimal realisation.

        Mode k's transfer from input j to output i is g[j, i] ω²/(s² + 2ζω s + ω²): its
        residue matrix gᵀ (ny, nu) has rank r ≤ min(nu, ny), and it takes r pole pairs
        (gᵀ = Σ σ_q u_q v_qᵀ: pair q driven by ω² σ_q v_q, read by u_q) — one pair with one
        input or one output, so the mode appears once in the poles and the read-outs
        whatever the number of inputs. The simulation (:meth:`output`) drives the mode
        from each input separately; both give the same response."""
        As, Bs, Cs = [], [], []
        for f, z, g in self.modes_of(th):
            w = 2 * np.pi * f
            U, sv, Vt = np.linalg.svd(np.asarray(g, float).T, full_matrices=False)
            keep = [q for q in range(sv.size) if sv[q] > 1e-12 * max(sv[0], 1e-300)] or [0]
            for q in keep:
                As.append(np.array([[0.0, 1.0], [-w * w, -2 * z * w]]))
                b = np.zeros((2, self.nu))
                b[1] = w * w * sv[q] * Vt[q]
                Bs.append(b)
                c = np.zeros((self.ny, 2))
                c[:, 0] = U[:, q]
                Cs.append(c)
        return As, Bs, Cs
