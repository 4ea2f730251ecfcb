"""Run a function in a fresh, spawned helper process, named by its module (not imported here).

The loop's process hands work that reads or parses files (SIGHUP's re-read, an operator
impact's window cut from its HDF5 wait recording) to a helper, and its HDF5 writer process is
started the same way (:func:`call` as the target): a
spawned interpreter (not a fork: nothing of the loop's threads or locks is copied) with its
own interpreter lock, so the parsing never holds the loop thread's. The function is named by
module and attribute (``"rigd.service.reader", "reload_files"``) and imported in the helper
only: the import contracts can then check that the loop's process never imports the readers.
What comes back is pickled (keep it small: arrays and a few scalars).
"""

from __future__ import annotations

import faulthandler
import importlib
import multiprocessing
import signal
from concurrent.futures import ProcessPoolExecutor
from typing import Any


def dump_stacks_on_sigusr2() -> None:
    """SIGUSR2 writes every thread's stack to stderr (:mod:`faulthandler`, in C: also while
    the interpreter is stuck); for where a hang stands. Main thread only; silent if not."""
    try:
        faulthandler.register(signal.SIGUSR2, all_threads=True)
    except (ValueError, RuntimeError, OSError, AttributeError):
        pass


def call(module: str, name: str, *args: Any) -> Any:
    """In the helper: import ``module`` and call its ``name(*args)`` (also the target of a
    long-lived spawned :class:`multiprocessing.Process`, such as the socket process).

    SIGUSR2 dumps the helper's threads to stderr (:func:`dump_stacks_on_sigusr2`)."""
    dump_stacks_on_sigusr2()
    return getattr(importlib.import_module(module), name)(*args)


def run(module: str, name: str, *args: Any, timeout_s: float = 300.0) -> Any:
    """``module.name(*args)`` run in a spawned helper process; its return value.

    Parameters
    ----------
    module, name : str
        Where the function is, e.g. ``"rigd.service.reader"``, ``"reload_files"``.
    timeout_s : float
        Longest wait for the result, s (a hung helper is left to end; TimeoutError).

    Raises
    ------
    Whatever the function raised (pickled back), TimeoutError, or
    concurrent.futures.process.BrokenProcessPool if the helper died.
    """
    ex = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
    try:
        return ex.submit(call, module, name, *args).result(timeout_s)
    finally:
        ex.shutdown(wait=False, cancel_futures=True)

