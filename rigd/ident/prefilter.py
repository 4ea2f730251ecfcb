"""Prefilters of Sec. 4.4, applied to a :class:`Record` before identification.

* **Run-out filter** F_r(φ): from a run-out record taken at the same operating point with the
  shaft not excited, the shaft displacement (minus its mean) is averaged in bins of the
  encoder angle φ; F_r(φ) is that binned mean, interpolated periodically, and
  ``e(t) - F_r(φ(t))`` removes the mass-unbalance and surface run-out response.
* **Offsets**: the mean of the first 2000 samples of every input and output is subtracted.
* **Median filter** of size 3 on the shaft displacements ``e_x, e_y``.

Each is switchable (:class:`PrefilterOptions`) and :func:`apply_prefilters` reports what it did.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field
from scipy.signal import medfilt

from rigd.configio import StrictModel
from rigd.data.record import BEARING_OUTPUTS, Record
from rigd.errors import InputError

#: operating points closer than this are "the same" (rpm, bar)
OMEGA_TOL_RPM = 50.0
P_TOL_BAR = 0.1


class PrefilterOptions(StrictModel):
    """Which prefilters to apply (all on by default; run-out only with a run-out record)."""

    offsets: bool = True
    offset_samples: int = Field(2000, gt=0)
    median: bool = True
    runout: bool = True
    runout_bins: int = Field(256, ge=8)


class RunoutFilter:
    """F_r(φ): synchronous response per channel as a function of the shaft angle.

    Parameters
    ----------
    phi : ndarray (n,)
        Encoder angle of the run-out record, rad (any range; wrapped to [0, 2π)).
    values : dict of str -> ndarray (n,)
        Channels of the run-out record (e.g. ``e_x``, ``e_y``).
    bins : int
        Number of angle bins.
    """

    def __init__(self, phi: np.ndarray, values: dict[str, np.ndarray], bins: int = 256):
        phi = np.mod(np.asarray(phi, float), 2 * np.pi)
        nb = int(max(8, min(bins, len(phi) // 20)))
        idx = np.minimum((phi / (2 * np.pi) * nb).astype(int), nb - 1)
        counts = np.bincount(idx, minlength=nb)
        self.bins = nb
        self.centres = (np.arange(nb) + 0.5) * 2 * np.pi / nb
        self.table: dict[str, np.ndarray] = {}
        filled = counts > 0
        if filled.sum() < 2:
            raise InputError("run-out record covers too few shaft angles (is the shaft "
                             "turning?)")
        for name, v in values.items():
            v = np.asarray(v, float) - np.mean(v)
            sums = np.bincount(idx, weights=v, minlength=nb)
            mean = np.zeros(nb)
            mean[filled] = sums[filled] / counts[filled]
            if not filled.all():  # fill empty bins periodically
                mean = np.interp(self.centres, self.centres[filled], mean[filled],
                                 period=2 * np.pi)
            self.table[name] = mean
        self.coverage = float(filled.mean())

    def __call__(self, name: str, phi: np.ndarray) -> np.ndarray:
        """F_r(φ) of channel ``name`` at angles ``phi`` (rad)."""
        return np.interp(np.mod(phi, 2 * np.pi), self.centres, self.table[name],
                         period=2 * np.pi)

    @classmethod
    def from_record(cls, runout: Record, channels=BEARING_OUTPUTS, bins: int = 256):
        if "phi" not in runout.columns:
            raise InputError("run-out record has no 'phi' column (the encoder angle is needed "
                             "to build the run-out filter F_r(phi))", runout.source)
        missing = [c for c in channels if c not in runout.columns]
        if missing:
            raise InputError(f"run-out record lacks column(s) {', '.join(missing)}",
                             runout.source)
        runout.check_finite(["phi", *channels], "the run-out filter")
        return cls(runout.col("phi"), {c: runout.col(c) for c in channels}, bins)


def check_operating_point(data: Record, runout: Record) -> None:
    """InputError unless both records were taken at the same (Ω, P_I)."""
    if abs(data.omega_rpm - runout.omega_rpm) > OMEGA_TOL_RPM:
        raise InputError(f"run-out record is at omega_rpm={runout.omega_rpm:g} but the data "
                         f"({data.source}) at omega_rpm={data.omega_rpm:g}; the run-out filter "
                         "must come from the same operating point", runout.source)
    pd, pr = data.p_inj_bar, runout.p_inj_bar
    if pd is not None and pr is not None and abs(pd - pr) > P_TOL_BAR:
        raise InputError(f"run-out record is at p_inj_bar={pr:g} but the data ({data.source}) "
                         f"at p_inj_bar={pd:g}; the run-out filter must come from the same "
                         "operating point", runout.source)


def apply_prefilters(record: Record, channels_in: list[str], channels_out: list[str],
                     options: PrefilterOptions | None = None,
                     runout: Record | None = None) -> tuple[Record, dict[str, Any]]:
    """Prefilter ``record`` (copy) for a model with the given input/output channels.

    Returns the filtered record and a report dict (what was applied, offsets, ...).
    """
    opt = options or PrefilterOptions()
    cols = {k: np.array(v, float) for k, v in record.columns.items()}
    report: dict[str, Any] = {"runout": False, "offsets": False, "median": False}
    shaft = [c for c in channels_out if c in BEARING_OUTPUTS]
    if runout is not None and opt.runout and shaft:
        check_operating_point(record, runout)
        if "phi" not in record.columns:
            raise InputError("data record has no 'phi' column, so the run-out filter cannot be "
                             "applied", record.source)
        record.check_finite(["phi"], "the run-out filter")
        F = RunoutFilter.from_record(runout, shaft, opt.runout_bins)
        removed = {}
        for c in shaft:
            corr = F(c, cols["phi"])
            cols[c] = cols[c] - corr
            removed[c] = float(np.std(F.table[c]))
        report["runout"] = {"source": runout.source, "bins": F.bins,
                            "coverage": F.coverage, "rms_removed": removed}
    if opt.median:
        for c in shaft:
            cols[c] = medfilt(cols[c], 3)
        report["median"] = {"size": 3, "channels": shaft} if shaft else False
    if opt.offsets:
        m = min(opt.offset_samples, max(record.n // 4, 1))
        offs = {}
        for c in list(dict.fromkeys(channels_in + channels_out)):
            if c in cols:
                offs[c] = float(np.mean(cols[c][:m]))
                cols[c] = cols[c] - offs[c]
        report["offsets"] = {"samples": m, "values": offs}
    return Record(cols, record.fs, dict(record.meta), record.source, record.lines,
                  record.first_sample, record.bad_cells), report
