"""Read gzip-compressed data files (``record.csv.gz``, ``record.mat.gz``) as the plain ones.

A file is gzip when it starts with gzip's two magic bytes (the ``.gz`` name is not trusted,
as no other extension is); its content then goes through the same reader and the same rules
as the uncompressed file, decompressed as it is read. A damaged or truncated gzip stream is
refused as one :class:`~rigd.errors.InputError` naming the file. HDF5 recordings are not read
compressed (HDF5 compresses inside the file): ``gunzip`` them first.
"""

from __future__ import annotations

import contextlib
import gzip
import io
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from rigd.errors import InputError

#: the two bytes every gzip stream starts with (RFC 1952)
GZIP_MAGIC = b"\x1f\x8b"
#: what a damaged gzip stream raises while it is read
_DAMAGED = (gzip.BadGzipFile, EOFError, zlib.error)


def is_gzip(path: str | Path) -> bool:
    """True if the file starts with the gzip magic bytes."""
    try:
        with open(path, "rb") as fh:
            return fh.read(2) == GZIP_MAGIC
    except OSError:
        return False


def inner_suffix(path: str | Path) -> str:
    """The lower-case suffix of the file's name without a trailing ``.gz`` (``a.csv.gz`` ->
    ``.csv``)."""
    p = Path(path)
    if p.suffix.lower() == ".gz":
        p = p.with_suffix("")
    return p.suffix.lower()


def head(path: str | Path, n: int) -> bytes:
    """The first ``n`` bytes of the file's content (decompressed if it is gzip); ``b""`` when
    it cannot be read."""
    try:
        if is_gzip(path):
            with gzip.open(path, "rb") as fh:
                return fh.read(n)
        with open(path, "rb") as fh:
            return fh.read(n)
    except (OSError, *_DAMAGED):
        return b""


def open_text(path: str | Path) -> TextIO:
    """Open a text data file for reading (UTF-8, newlines as written), decompressing a gzip
    one. Raises OSError as :func:`open` does."""
    if is_gzip(path):
        return gzip.open(path, "rt", encoding="utf-8", newline="")
    return open(path, encoding="utf-8", newline="")  # noqa: SIM115 - the caller closes it


def read_bytes(path: str | Path) -> io.BytesIO:
    """The whole (decompressed) content of a binary data file, for readers that take a file
    object (scipy.io.loadmat, h5py).

    Raises
    ------
    InputError
        A damaged or truncated gzip stream.
    """
    with damaged_as_input_error(path), gzip.open(path, "rb") as fh:
        return io.BytesIO(fh.read())


@contextlib.contextmanager
def damaged_as_input_error(path: str | Path) -> Iterator[None]:
    """Turn a damaged gzip stream met while reading into one InputError naming the file."""
    try:
        yield
    except _DAMAGED as exc:
        raise InputError(f"damaged gzip file (cannot decompress: {exc})", str(path)) from None
