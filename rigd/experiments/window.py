"""An operator impact's window, cut from its wait recording — in a spawned helper process.

``trigger: operator`` records up to ``timeout_s`` while the operator hits; the point keeps
the window of ``n_pre`` + ``n_post`` frames around the first sample where ``|f_axis| >=
trigger_n``. Reading the wait recording and writing the window is HDF5 work (h5py holds the
interpreter lock while it reads or writes): it runs here, in a helper the experiment spawns by
module name (:func:`rigd.spawn.run`), never in the loop's process, which only waits for the
answer (import contract: the daemon's process never imports h5py).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rigd.data.h5io import read_h5, write_h5
from rigd.experiments.points import PointFailed


def cut_hit_window(wait_path: str, path: str, axis: str, trigger_n: float, timeout_s: float,
                   n_pre: int, n_post: int, meta: dict[str, Any]) -> int:
    """Write the window around the first hit of ``wait_path`` into ``path``; its frames.

    Parameters
    ----------
    wait_path, path : str
        The wait recording (read) and the point's record (written, atomically).
    axis : {"x", "y"}
        Hammer axis: the force channel ``f_<axis>``, N.
    trigger_n : float
        Force threshold, N.
    timeout_s : float
        The wait's length, s (for the message).
    n_pre, n_post : int
        Frames kept before and from the first sample at or above the threshold.
    meta : dict
        Added to the record's metadata.

    Raises
    ------
    PointFailed
        No hit above the threshold, or one too close to an end of the wait.
    """
    rec = read_h5(Path(wait_path))
    f = rec.col(f"f_{axis}")
    above = np.flatnonzero(np.abs(f) >= trigger_n)
    if above.size == 0:
        raise PointFailed(f"no hammer hit above {trigger_n:g} N on f_{axis} "
                          f"within {timeout_s:g} s")
    i = int(above[0])
    if i < n_pre or i + n_post > rec.n:
        raise PointFailed("hammer hit too close to the start or end of the wait window")
    win = rec.slice(i - n_pre, i + n_post)
    win.meta.update(meta)
    write_h5(Path(path), win, replace=False)     # a point's record: never over a file
    return win.n
