"""Data layer: the in-memory :class:`Record`, and readers/writers for CSV and HDF5.

Every modelling command obtains its data through :func:`rigd.data.io.load_record`, which
accepts the project's HDF5 recordings and the interchange CSV (``../shared/data-format.md``),
and plain CSV files when their sample rate is given (``fs=``). See docs/data.md.
"""

from rigd.data.io import load_record
from rigd.data.record import Record

__all__ = ["Record", "load_record"]
