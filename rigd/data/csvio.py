"""Strict reader and streaming writer of the interchange CSV (``../shared/data-format.md``).

Layout::

    # rig-data: 1
    # fs: 5000            # sample rate, Hz (required)
    # omega_rpm: 0        # rotor records
    # p_inj_bar: 4.0      # rotor records
    t,r_x,r_y,u_x,u_y,e_x,e_y,phi
    0.0,1.0,-1.0,...

The reader refuses a file that breaks the spec with one :class:`~rigd.errors.InputError`
naming the file, the line and the problem (see :data:`PROBLEMS` for the list); it never
returns a partial record. Cells that are not numbers (empty, text, NaN, Inf) are kept as NaN
and refused when a command uses their column (:meth:`Record.check_finite`, one line naming
the file, line, column and sample): an unused column with empty cells does not refuse the
record. ``t`` is always in use (checked against ``fs``). Rows are parsed in blocks with
numpy, so a 131,072-row file reads in a fraction of a second and the temporary text of only
one block is held at a time.

The writer formats every number with Python's shortest round-trip ``repr``: a file written by
:func:`write_csv` / :func:`rigd.data.export.export_csv` reads back bit-for-bit.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import yaml

from rigd.data import compressed
from rigd.data.record import BAD_CELLS_KEPT, Record
from rigd.errors import InputError

#: Metadata keys with a meaning to the reader.
KNOWN_KEYS = ("rig-data", "fs", "omega_rpm", "p_inj_bar", "kind", "inputs", "outputs")
#: Kinds of bad file the reader refuses (documentation; each has a test).
PROBLEMS = (
    "empty file", "no header row (metadata only)", "header only, no data rows",
    "missing fs", "fs not a positive finite number", "bad metadata YAML", "metadata key twice",
    "missing omega_rpm / p_inj_bar for rotor data", "missing required column (t; phi when "
    "omega_rpm > 0)", "declared inputs/outputs not among the columns", "duplicate column",
    "empty or quoted column name", "ragged row",
    "non-numeric, empty, NaN or Inf cell in a column in use (when used; t: always)",
    "non-monotonic t", "t inconsistent with fs", "'#' line after the header",
    "unsupported rig-data version", "inputs without outputs (or the reverse)",
)
#: Rows parsed per block.
BLOCK_ROWS = 65536

_KEY_RE = re.compile(r"^\s*([A-Za-z_][\w\-]*)\s*:(.*)$")
CONVERT_HINT = ("to bring in a plain CSV (e.g. Silverbox), convert it: rigd export --from-csv "
                "RAW.csv --fs HZ --inputs COL[,COL] --outputs COL[,COL] -o OUT.csv")


def _err(path: str, line: int | None, msg: str) -> InputError:
    return InputError(msg, f"{path}:{line}" if line else path)


def _as_number(value: Any, key: str, path: str, line: int) -> float:
    """A metadata number (YAML int/float, or a numeric string such as ``5e3``)."""
    if isinstance(value, bool) or value is None:
        raise _err(path, line, f"{key} must be a number, got {value!r}")
    if isinstance(value, (int, float)):
        return float(value)
    try:
        return float(str(value).strip())
    except ValueError:
        raise _err(path, line, f"{key} must be a number, got {value!r}") from None


def _parse_meta_line(body: str, path: str, lineno: int) -> tuple[str | None, Any]:
    """Parse the text after ``#``: ``(key, value)``, or ``(None, text)`` for a free comment."""
    try:
        data = yaml.safe_load(body)
    except yaml.YAMLError as exc:
        m = _KEY_RE.match(body)
        if m and m.group(1) not in KNOWN_KEYS:
            return m.group(1), m.group(2).strip()      # free-form value of an unknown key
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise _err(path, lineno, f"bad metadata YAML: {problem}: {body.strip()!r}") from None
    if data is None:
        return None, None
    if isinstance(data, dict):
        if len(data) != 1:
            raise _err(path, lineno, f"bad metadata: one 'key: value' per line, got "
                                     f"{body.strip()!r}")
        (key, value), = data.items()
        return str(key), value
    return None, str(data)                                # free-form comment line


def _names(value: Any, key: str, path: str, line: int) -> list[str]:
    if isinstance(value, str):
        value = [v.strip() for v in value.split(",") if v.strip()]
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise _err(path, line, f"{key} must be a non-empty list of column names, got {value!r}")
    return list(value)


class _Lines:
    """Iterate over a text file's lines with 1-based numbers, skipping empty lines."""

    def __init__(self, fh: TextIO):
        self.fh = fh
        self.lineno = 0

    def __iter__(self) -> Iterator[tuple[int, str]]:
        for raw in self.fh:
            self.lineno += 1
            line = raw.rstrip("\r\n")
            if line.strip():
                yield self.lineno, line


def read_header(fh: TextIO, path: str) -> tuple[dict[str, Any], dict[str, int], list[str], int,
                                                  Iterator[tuple[int, str]]]:
    """Read the metadata and header row.

    Returns
    -------
    meta, meta_lines, names, header_line, rest
        Metadata dict, line of every key, column names, the header's line number and an
        iterator over the remaining ``(lineno, text)`` non-empty lines.
    """
    lines = iter(_Lines(fh))
    meta: dict[str, Any] = {}
    where: dict[str, int] = {}
    comments: list[str] = []
    header = None
    try:
        for lineno, text in lines:
            if text.lstrip().startswith("#"):
                key, value = _parse_meta_line(text.lstrip()[1:], path, lineno)
                if key is None:
                    if value:
                        comments.append(value)
                    continue
                if key in where:
                    raise _err(path, lineno, f"metadata key {key!r} given twice (first on line "
                                             f"{where[key]})")
                meta[key] = value
                where[key] = lineno
                continue
            header = (lineno, text)
            break
    except UnicodeDecodeError:
        raise _err(path, None, "not a text file (cannot decode as UTF-8)") from None
    if header is None:
        if not meta and not comments:
            raise _err(path, None, "empty file")
        raise _err(path, None, "no header row: the file holds metadata only")
    if comments:
        meta["comments"] = comments
    hline, htext = header
    names = [c.strip() for c in htext.split(",")]
    if any(n.startswith('"') or n.startswith("'") for n in names):
        if not meta:
            raise _err(path, hline, "quoted header and no '# fs:' metadata: not a rig-data "
                                    "interchange file; " + CONVERT_HINT)
        raise _err(path, hline, "quoted column name: the format has no quoting")
    for i, n in enumerate(names):
        if not n:
            hint = " (trailing comma?)" if i == len(names) - 1 else ""
            raise _err(path, hline, f"empty column name in column {i + 1}{hint}")
    seen: dict[str, int] = {}
    for i, n in enumerate(names):
        if n in seen:
            raise _err(path, hline, f"duplicate column {n!r} (columns {seen[n] + 1} and {i + 1})")
        seen[n] = i
    return meta, where, names, hline, lines


def check_meta(meta: dict[str, Any], where: dict[str, int], names: list[str], path: str,
               hline: int) -> tuple[float, dict[str, Any]]:
    """Validate the metadata against the spec; returns ``(fs, meta)`` with typed values."""
    if not meta:
        raise _err(path, None, "no metadata lines (missing '# fs: ...'): not a rig-data "
                               "interchange file; " + CONVERT_HINT)
    if "rig-data" in meta:
        ver = meta["rig-data"]
        if ver not in (1, "1", 1.0):
            raise _err(path, where["rig-data"], f"unsupported rig-data version {ver!r} "
                                                "(this reader knows version 1)")
    if "fs" not in meta:
        raise _err(path, None, "missing required metadata 'fs' (sample rate, Hz), "
                               "e.g. '# fs: 5000'")
    fs = _as_number(meta["fs"], "fs", path, where["fs"])
    if not (math.isfinite(fs) and fs > 0):
        raise _err(path, where["fs"], f"fs must be a positive finite number of Hz, got "
                                      f"{meta['fs']!r}")
    meta["fs"] = fs
    has_in, has_out = "inputs" in meta, "outputs" in meta
    if has_in != has_out:
        k = "inputs" if has_in else "outputs"
        raise _err(path, where[k], f"{k} declared without "
                                   f"{'outputs' if has_in else 'inputs'}: declare both")
    if has_in:
        for k in ("inputs", "outputs"):
            meta[k] = _names(meta[k], k, path, where[k])
            missing = [c for c in meta[k] if c not in names]
            if missing:
                raise _err(path, hline, f"column(s) {', '.join(map(repr, missing))} declared in "
                                        f"{k} (line {where[k]}) are not in the header")
        for k in ("omega_rpm", "p_inj_bar"):
            if k in meta and meta[k] is not None:
                meta[k] = _as_number(meta[k], k, path, where[k])
    else:  # rotor record
        for k in ("omega_rpm", "p_inj_bar"):
            if k not in meta:
                raise _err(path, None, f"missing required metadata {k!r} for rotor data "
                                       "(or declare generic 'inputs'/'outputs')")
            meta[k] = _as_number(meta[k], k, path, where[k])
            if not math.isfinite(meta[k]):
                raise _err(path, where[k], f"{k} must be finite, got {meta[k]!r}")
        if meta["p_inj_bar"] < 0:
            raise _err(path, where["p_inj_bar"], f"p_inj_bar must be >= 0 (manometric), got "
                                                 f"{meta['p_inj_bar']!r}")
        if "t" not in names:
            raise _err(path, hline, "missing required column 't' (rotor data)")
        if meta["omega_rpm"] > 0 and "phi" not in names:
            raise _err(path, hline, f"missing required column 'phi' (omega_rpm = "
                                    f"{meta['omega_rpm']:g} > 0)")
    if "kind" in meta and meta["kind"] is not None:
        meta["kind"] = str(meta["kind"])
    return fs, meta


def _parse_block(block: list[tuple[int, str]], names: list[str], path: str,
                 bad: dict[str, dict[int, str]] | None = None) -> np.ndarray:
    """Parse rows into an array; ragged rows are refused.

    A cell that is not a number (empty, text) becomes NaN and its text is remembered in
    ``bad`` (column -> {line: text}, at most :data:`rigd.data.record.BAD_CELLS_KEPT` per
    column): only the columns a command uses are checked (:meth:`Record.check_finite`), so an
    unused column with empty cells does not refuse the record.
    """
    ncol = len(names)
    for lineno, text in block:
        if text.count(",") != ncol - 1:
            if text.lstrip().startswith("#"):
                raise _err(path, lineno, "'#' line after the header (metadata must come first)")
            got = text.count(",") + 1
            hint = " (trailing comma?)" if text.rstrip().endswith(",") else ""
            raise _err(path, lineno, f"ragged row: {got} cells, header has {ncol}{hint}")
    joined = ",".join(text for _, text in block).split(",")
    try:
        return np.array(joined, dtype=np.float64).reshape(len(block), ncol)
    except ValueError:
        pass
    cells = np.array(joined, dtype=object).reshape(len(block), ncol)
    arr = np.empty((len(block), ncol))
    for c, name in enumerate(names):
        try:
            arr[:, c] = cells[:, c].astype(np.float64)
            continue
        except ValueError:
            pass
        kept = bad.setdefault(name, {}) if bad is not None else {}
        for r, cell in enumerate(cells[:, c]):
            try:
                arr[r, c] = float(cell)
            except ValueError:
                arr[r, c] = np.nan
                if len(kept) < BAD_CELLS_KEPT:
                    kept[block[r][0]] = str(cell)
    return arr


def check_t_column(columns: dict[str, np.ndarray], lines: np.ndarray, bad: dict[str, dict],
                   path: str) -> None:
    """The reader uses ``t`` (checked against ``fs``): it must be complete."""
    t = columns.get("t")
    if t is None:
        return
    nf = ~np.isfinite(t)
    if nf.any():
        i = int(np.argmax(nf))
        text = bad.get("t", {}).get(int(lines[i]))
        what = (f"non-numeric cell {text.strip()!r}" if text and text.strip() else
                "empty cell" if text is not None else repr(float(t[i])))
        raise _err(path, int(lines[i]), f"{what} in column 't' (the time column must be "
                                        "complete: it is checked against fs)")


def check_time(t: np.ndarray, fs: float, lines: np.ndarray, path: str) -> None:
    """``t`` must increase strictly and stay within half a sample period of ``t0 + i/fs``."""
    if len(t) < 2:
        return
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        raise _err(path, int(lines[i]),
                   f"t not increasing: t = {float(t[i])!r} after {float(t[i - 1])!r}")
    dev = np.abs(t - (t[0] + np.arange(len(t)) / fs))
    tol = 0.5 / fs
    bad = np.flatnonzero(dev > tol)
    if bad.size:
        i = bad[0]
        raise _err(path, int(lines[i]),
                   f"t inconsistent with fs = {fs:g} Hz: t = {float(t[i])!r}, "
                   f"expected {float(t[0] + i / fs)!r} (tolerance half a sample, {tol:.3g} s)")


def read_csv(path: str | Path) -> Record:
    """Read an interchange CSV strictly into a :class:`Record`.

    Raises
    ------
    InputError
        Any breach of the spec, naming the file, the line and the problem.
    """
    spath = str(path)
    try:
        fh = compressed.open_text(path)
    except FileNotFoundError:
        raise _err(spath, None, "no such file") from None
    except OSError as exc:
        raise _err(spath, None, f"cannot read: {exc.strerror or exc}") from None
    with fh, compressed.damaged_as_input_error(spath):
        meta, where, names, hline, rest = read_header(fh, spath)
        fs, meta = check_meta(meta, where, names, spath, hline)
        blocks: list[np.ndarray] = []
        line_blocks: list[np.ndarray] = []
        block: list[tuple[int, str]] = []
        bad: dict[str, dict[int, str]] = {}
        try:
            for item in rest:
                block.append(item)
                if len(block) >= BLOCK_ROWS:
                    blocks.append(_parse_block(block, names, spath, bad))
                    line_blocks.append(np.fromiter((ln for ln, _ in block), dtype=np.int64))
                    block = []
        except UnicodeDecodeError:
            raise _err(spath, None, "not a text file (cannot decode as UTF-8)") from None
        if block:
            blocks.append(_parse_block(block, names, spath, bad))
            line_blocks.append(np.fromiter((ln for ln, _ in block), dtype=np.int64))
    if not blocks:
        raise _err(spath, hline, "header only: no data rows")
    data = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
    del blocks
    columns = {n: np.ascontiguousarray(data[:, i]) for i, n in enumerate(names)}
    lines = np.concatenate(line_blocks)
    if "t" in columns:
        check_t_column(columns, lines, bad, spath)
        check_time(columns["t"], fs, lines, spath)
    meta.pop("fs", None)
    meta.pop("rig-data", None)
    return Record(columns, fs, meta, spath, lines, 0, bad)


# --- writing ---------------------------------------------------------------------------------
def _yaml_scalar(value: Any) -> str:
    """One-line YAML for a metadata value that reads back to the same value."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isnan(v):
            return ".nan"
        if math.isinf(v):
            return ".inf" if v > 0 else "-.inf"
        s = repr(v)
        if "." not in s:  # PyYAML (YAML 1.1) reads '1e-05' as a string
            s = s.replace("e", ".0e") if "e" in s else s + ".0"
        return s
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_yaml_scalar(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_yaml_scalar(v)}"
                               for k, v in value.items()) + "}"
    return json.dumps(str(value))  # JSON strings are YAML double-quoted scalars


def metadata_lines(fs: float, meta: dict[str, Any]) -> list[str]:
    """``# key: value`` lines for a record's metadata (``rig-data`` and ``fs`` first)."""
    out = ["# rig-data: 1", f"# fs: {_yaml_scalar(float(fs))}"]
    for key, value in meta.items():
        if key in ("rig-data", "fs", "comments") or not _KEY_RE.match(f"{key}:"):
            continue
        out.append(f"# {key}: {_yaml_scalar(value)}")
    for c in meta.get("comments") or ():
        out.append("# " + str(c).replace("\n", " "))
    return out


def format_rows(block: np.ndarray) -> str:
    """Rows of a float64 (n, C) block as CSV text, shortest round-trip repr per number."""
    rows = block.tolist()
    return "".join(",".join(map(repr, row)) + "\n" for row in rows)


def check_finite_block(block: np.ndarray, names: list[str], where: str, first_row: int) -> None:
    """Refuse to write NaN/Inf (the format does not allow them)."""
    finite = np.isfinite(block)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        raise InputError(f"{float(block[r, c])!r} in channel {names[c]!r} at sample "
                         f"{first_row + r}: NaN/Inf cannot be written to the interchange CSV",
                         where)


def write_blocks(fh: TextIO, fs: float, meta: dict[str, Any], names: list[str],
                 blocks: Iterable[np.ndarray], where: str) -> int:
    """Write metadata, header and row blocks to an open text file; returns the row count."""
    fh.write("\n".join(metadata_lines(fs, meta)) + "\n")
    fh.write(",".join(names) + "\n")
    n = 0
    for block in blocks:
        check_finite_block(block, names, where, n)
        fh.write(format_rows(block))
        n += len(block)
    return n


def write_csv(path: str | Path, record: Record, *, block_rows: int = BLOCK_ROWS,
              replace: bool = True) -> int:
    """Write ``record`` as an interchange CSV atomically; returns the number of rows
    (``replace=False``: FileExistsError rather than replace a file)."""
    from rigd.fileio import atomic_open

    names = list(record.columns)
    if "t" in names:  # t first, for people
        names.remove("t")
        names.insert(0, "t")

    def blocks():
        for s in range(0, max(record.n, 1) if record.n else 0, block_rows):
            yield np.column_stack([record.columns[k][s:s + block_rows] for k in names]
                                  ).astype(np.float64, copy=False)

    with atomic_open(path, "w", replace=replace, encoding="utf-8", newline="\n") as fh:
        return write_blocks(fh, record.fs, record.meta, names, blocks(), str(path))
