"""Bring in a plain CSV that has no rig-data metadata (e.g. the Silverbox benchmark file).

Such files carry only a header row and numbers, often with quoted names (``"V1","V2",``) and a
trailing comma on every line. The user supplies what the file cannot say — the sample rate and
which columns are inputs and outputs (or, for rotor data, Ω and P_I) — and gets a
:class:`~rigd.data.record.Record` checked by the same rules as the strict reader. The usual
way is to convert once to an interchange file::

    rigd export --from-csv SNLS80mV.csv --fs 610.3515625 --inputs V1 --outputs V2 -o sb.csv

or to read it directly with ``load_record(path, fs=..., inputs=[...], outputs=[...])``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from rigd.data import compressed, csvio
from rigd.data.record import Record
from rigd.errors import InputError


def read_raw_csv(path: str | Path, *, fs: float, inputs: list[str] | None = None,
                 outputs: list[str] | None = None, meta: dict[str, Any] | None = None) -> Record:
    """Read a plain CSV (header row + numeric rows) with user-supplied metadata.

    Parameters
    ----------
    path : path
        The file. Quoted header names and one trailing comma per line are accepted; lines
        starting with ``#`` before the header are skipped.
    fs : float
        Sample rate, Hz.
    inputs, outputs : list of str, optional
        Generic record: excitation and response columns (both or neither).
    meta : dict, optional
        Further metadata (``omega_rpm``, ``p_inj_bar``, ``kind``, ...). A rotor record (no
        inputs/outputs) needs ``omega_rpm`` and ``p_inj_bar``, as in the strict reader.

    Raises
    ------
    InputError
        Ragged rows, missing columns, bad ``fs``, a bad ``t`` cell: file, line and problem
        (other bad cells are refused when their column is used: ``Record.check_finite``).
    """
    spath = str(path)
    meta = dict(meta or {})
    meta["fs"] = fs
    if inputs is not None:
        meta["inputs"] = list(inputs)
    if outputs is not None:
        meta["outputs"] = list(outputs)
    try:
        fh = compressed.open_text(path)
    except FileNotFoundError:
        raise InputError("no such file", spath) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", spath) from None
    with fh, compressed.damaged_as_input_error(spath):
        lines = iter(csvio._Lines(fh))
        hline, names, trailing = _header(lines, spath)
        where = {k: None for k in meta}
        fs_, meta = csvio.check_meta(meta, where, names, spath, hline)
        bad: dict[str, dict[int, str]] = {}
        data, lines = _rows(lines, names, trailing, spath, hline, bad)
    columns = {n: np.ascontiguousarray(data[:, i]) for i, n in enumerate(names)}
    if "t" in columns:
        csvio.check_t_column(columns, lines, bad, spath)
        csvio.check_time(columns["t"], fs_, lines, spath)
    meta.pop("fs", None)
    meta.setdefault("source_file", Path(spath).name)
    return Record(columns, fs_, meta, spath, lines, 0, bad)


def _header(lines, spath: str) -> tuple[int, list[str], bool]:
    """(line number, column names, whether every line ends in a trailing comma) of the
    header: the first line not starting with ``#``; names must be non-empty, not numbers,
    and unique."""
    header = None
    try:
        for lineno, text in lines:
            if not text.lstrip().startswith("#"):
                header = (lineno, text)
                break
    except UnicodeDecodeError:
        raise InputError("not a text file (cannot decode as UTF-8)", spath) from None
    if header is None:
        raise InputError("empty file", spath)
    hline, htext = header
    names = [c.strip() for c in next(csv.reader([htext]))]
    trailing = bool(names) and names[-1] == ""
    if trailing:
        names = names[:-1]
    for i, n in enumerate(names):
        if not n:
            raise InputError(f"empty column name in column {i + 1}", f"{spath}:{hline}")
        try:
            float(n)
        except ValueError:
            pass
        else:
            raise InputError(f"no header row (first line holds numbers, {n!r}): add a "
                             "header line with column names", f"{spath}:{hline}")
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError(f"duplicate column {dup!r}", f"{spath}:{hline}")
    return hline, names, trailing


def _rows(lines, names: list[str], trailing: bool, spath: str, hline: int,
          bad: dict[str, dict[int, str]]) -> tuple[np.ndarray, np.ndarray]:
    """(samples (n, len(names)), file line of each row) of the data rows, parsed in blocks
    (bad cells recorded in ``bad``); a trailing comma, when the header has one, is required
    on every row."""
    blocks, line_blocks, block = [], [], []

    def flush():
        if trailing:
            fixed = []
            for ln, tx in block:
                if not tx.rstrip().endswith(","):
                    raise InputError(f"ragged row: {tx.count(',') + 1} cells, header has "
                                     f"{len(names)} and a trailing comma", f"{spath}:{ln}")
                fixed.append((ln, tx.rstrip()[:-1]))
        else:
            fixed = block
        blocks.append(csvio._parse_block(fixed, names, spath, bad))
        line_blocks.append(np.fromiter((ln for ln, _ in block), dtype=np.int64))

    for item in lines:
        block.append(item)
        if len(block) >= csvio.BLOCK_ROWS:
            flush()
            block = []
    if block:
        flush()
    if not blocks:
        raise InputError("header only: no data rows", f"{spath}:{hline}")
    data = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
    return data, np.concatenate(line_blocks)
