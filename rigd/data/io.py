"""One entry point for every modelling command: :func:`load_record`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rigd.data.record import Record
from rigd.errors import InputError


def load_record(path: str | Path, *, fs: float | None = None,
                inputs: list[str] | str | None = None, outputs: list[str] | str | None = None,
                meta: dict[str, Any] | None = None, var: str | None = None,
                time_column: str | int | None = None) -> Record:
    """Load a measurement record from an HDF5 recording, a CSV file or a MATLAB file.

    The format is recognised by content: the HDF5 signature means a rigd recording
    (:func:`rigd.data.h5io.read_h5`); anything else is read as the strict interchange CSV
    (:func:`rigd.data.csvio.read_csv`). Passing ``fs`` reads a *plain* CSV without rig-data
    metadata instead (:func:`rigd.data.rawcsv.read_raw_csv`, e.g. the Silverbox file), with
    ``inputs``/``outputs`` (generic record) or ``meta={"omega_rpm":..,"p_inj_bar":..}``.
    A MATLAB file (``MATLAB`` text header: v5/v7, or v7.3 = HDF5 behind it) is read by
    :func:`rigd.data.matio.read_mat` with ``var``, ``inputs``/``outputs`` (1-based columns or
    variable names), ``time_column`` and/or ``fs``. A CSV or MATLAB file compressed with gzip
    (``record.csv.gz``) is read as the plain one (:mod:`rigd.data.compressed`).

    Parameters
    ----------
    path : path
        ``.h5``/``.hdf5`` recording, ``.csv`` or ``.mat`` file, the latter two optionally
        gzip-compressed (the extension is not trusted).
    fs : float, optional
        Sample rate, Hz, of a plain CSV (only for plain CSV files).
    inputs, outputs : list of str or comma-separated str, optional
        Input/output columns of a plain CSV (generic record).
    meta : dict, optional
        Extra metadata of a plain CSV.
    var, time_column : optional
        MATLAB files only: the matrix holding the samples, the 1-based time column.

    Returns
    -------
    Record

    Raises
    ------
    InputError
        Missing/unreadable file, or any breach of the format: one message naming the file,
        the line (CSV) and the problem.
    """
    from rigd.data import compressed, csvio, h5io, matio, rawcsv

    p = Path(path)
    if not p.exists():
        raise InputError("no such file", str(path))
    if p.is_dir():
        raise InputError("is a directory, not a data file", str(path))
    if matio.is_mat(p):
        return matio.read_mat(p, var=var, inputs=inputs, outputs=outputs,
                              time_column=time_column, fs=fs, meta=meta)
    if var is not None or time_column is not None:
        raise InputError("--var/--time-column apply to MATLAB .mat files only", str(path))
    suffix = compressed.inner_suffix(p)
    if suffix == ".mat":
        raise InputError("named like a MATLAB file but has no MAT-file header (v4 files are "
                         "not read: save with -v7 or -v7.3)", str(path))
    if compressed.is_gzip(p) and (suffix in (".h5", ".hdf5")
                                  or compressed.head(p, 8) == h5io.HDF5_MAGIC):
        raise InputError("a gzip-compressed HDF5 recording is not read: decompress it first "
                         "(gunzip)", str(path))
    if h5io.is_hdf5(p):
        if fs is not None or inputs or outputs:
            raise InputError("fs/inputs/outputs options apply to plain CSV files only, not to "
                             "an HDF5 recording", str(path))
        return h5io.read_h5(p)
    if suffix in (".h5", ".hdf5"):
        raise InputError("named like HDF5 but is not an HDF5 file", str(path))
    if fs is not None:
        return rawcsv.read_raw_csv(p, fs=fs, inputs=_split(inputs), outputs=_split(outputs),
                                   meta=meta)
    if inputs or outputs or meta:
        raise InputError("inputs/outputs/meta options need fs (they describe a plain CSV)",
                         str(path))
    return csvio.read_csv(p)


def _split(v: list[str] | str | None) -> list[str] | None:
    if v is None:
        return None
    if isinstance(v, str):
        return [s.strip() for s in v.split(",") if s.strip()]
    return list(v)
