"""The generated record: samples, names, units and the truth; CSV/MAT writers for CLI tests."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


def add_noise(y: np.ndarray, snr_db: float, rng: np.random.Generator) -> np.ndarray:
    """``y`` plus white noise ``snr_db`` below each channel's standard deviation."""
    y = np.asarray(y, float)
    return y + 10 ** (-snr_db / 20) * np.std(y, axis=0) * rng.standard_normal(y.shape)


@dataclass
class Generated:
    """A generated record.

    Attributes
    ----------
    u, y : ndarray (n, nu), (n, ny)
        Inputs and (noisy) outputs, in ``units``.
    fs : float
        Sample rate (Hz).
    inputs, outputs : list of str
        Channel names.
    units : dict
        Unit per channel name.
    truth : dict
        What the system is: ``kind`` and, as they apply, ``delays`` (samples, per input),
        ``order`` (states), ``poles`` (continuous, rad/s), ``modes`` ([(f Hz, ζ)]),
        ``time_constants`` (s), ``dc_gain``, ``integrator``, ``closed_loop``,
        ``nonlinearity`` and the parameters used.
    y_clean : ndarray
        Outputs without noise.
    """

    u: np.ndarray
    y: np.ndarray
    fs: float
    inputs: list[str]
    outputs: list[str]
    units: dict[str, str]
    truth: dict[str, Any] = field(default_factory=dict)
    y_clean: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.u.shape[0])

    def columns(self) -> tuple[list[str], np.ndarray]:
        """Header and (n, 1 + nu + ny) table: time (s), inputs, outputs."""
        t = np.arange(self.n) / self.fs
        return (["t", *self.inputs, *self.outputs], np.column_stack([t, self.u, self.y]))

    def record(self):
        """The same samples as a :class:`rigd.data.record.Record` (time column ``t``, names
        and units in its metadata), for calling rigd's Python API directly."""
        from rigd.data.record import Record

        head, data = self.columns()
        return Record(dict(zip(head, data.T)), self.fs,
                      {"inputs": list(self.inputs), "outputs": list(self.outputs),
                       "units": dict(self.units)}, f"<generated {self.truth.get('kind')}>")

    def write_csv(self, path: str | Path) -> Path:
        """Plain CSV (header line, comma-separated, time column ``t`` first)."""
        head, data = self.columns()
        np.savetxt(path, data, delimiter=",", header=",".join(head), comments="", fmt="%.17g")
        return Path(path)

    def write_mat(self, path: str | Path, var: str = "data", v73: bool = False) -> Path:
        """The same table in a MATLAB file: v5 (scipy.io.savemat) or v7.3 (HDF5 with MATLAB's
        layout: the dataset stored transposed, ``MATLAB_class`` attribute)."""
        _, data = self.columns()
        if not v73:
            import scipy.io

            scipy.io.savemat(path, {var: data})
            return Path(path)
        import h5py

        with h5py.File(path, "w", userblock_size=512) as f:
            ds = f.create_dataset(var, data=data.T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")
        with open(path, "r+b") as fh:   # MATLAB's 128-byte text header in the user block
            head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created by: tests.gen HDF5 schema"
            fh.write(head.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
        return Path(path)

    def cli_args(self) -> list[str]:
        """``--inputs``/``--outputs`` options of the CSV written by :meth:`write_csv`."""
        return ["--inputs", ",".join(self.inputs), "--outputs", ",".join(self.outputs)]
