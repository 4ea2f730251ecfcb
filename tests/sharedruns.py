"""Expensive outputs made once per test run and read by every test that needs them (import as
``from sharedruns import shared_folder``; used by the session fixtures of ``tests/conftest.py``).

One folder per name under a root that every process of the run sees: ``$RIGD_TEST_SHARED``
when set (``make test`` sets it to one temporary folder for both of its parts, so the
timing-sensitive part reuses what the compute part made, and removes it at the end), else
the session's pytest base folder (under pytest-xdist its parent, which the workers share).
An exclusive ``flock`` per name: the first process makes the folder, the others wait for it
and read it; a failed attempt leaves no ``.done`` mark and the next process makes it anew
(so a failure is reported by every test that needs the folder, never hidden).
:func:`shared_value` is the same for one picklable result (a diagnosis, a fit).
"""

from __future__ import annotations

import fcntl
import os
import pickle
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ENV = "RIGD_TEST_SHARED"


def shared_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder the processes of this test run share (see the module docstring)."""
    env = os.environ.get(ENV)
    if env:
        return Path(env)
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def shared_folder(name: str, make: Callable[[Path], None],
                  tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``root/name``, made by ``make(folder)`` in the first process that asks for it.

    Parameters
    ----------
    name : str
        The folder's name under :func:`shared_root` (one name per kind of output).
    make : callable
        Writes the output into the folder it is given (absent before the call); raises or
        fails an assertion when it cannot.
    tmp_path_factory : pytest.TempPathFactory
        The session's, for the root when ``$RIGD_TEST_SHARED`` is not set.

    Returns
    -------
    Path
        The finished folder (tests only read it).
    """
    root = shared_root(tmp_path_factory)
    root.mkdir(parents=True, exist_ok=True)
    out, done = root / name, root / f"{name}.done"
    with open(root / f"{name}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)          # released when the file is closed
        if not done.exists():
            shutil.rmtree(out, ignore_errors=True)  # what a failed earlier attempt left
            make(out)
            done.touch()
    return out


def shared_value(name: str, make: Callable[[], Any],
                 tmp_path_factory: pytest.TempPathFactory) -> Any:
    """``make()``, computed by the first process of the run that asks and read back (pickled
    in ``root/name``) by every other one: an expensive result two test modules, or two tests
    of one module on two pytest-xdist workers, share.

    Parameters
    ----------
    name : str
        The folder's name under :func:`shared_root` (one name per result).
    make : callable
        Returns the result (picklable); raises or fails an assertion when it cannot.
    tmp_path_factory : pytest.TempPathFactory
        The session's, for the root when ``$RIGD_TEST_SHARED`` is not set.

    Returns
    -------
    object
        A fresh copy of the result (unpickled for each call: a test may change it).
    """
    def write(out: Path) -> None:
        value = make()
        out.mkdir()
        (out / "value.pkl").write_bytes(pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))

    return pickle.loads((shared_folder(name, write, tmp_path_factory) / "value.pkl").read_bytes())
