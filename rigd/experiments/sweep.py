"""Operating points of a sweep: setting Ω × P_I and checking that the rig has settled.

* ``set_point_by: loop`` — ``loop.set_operating_point(Ω, P_I)``: on the simulated plant it is
  set directly; on a rig the loop passes it to the slow drivers (turbine speed and pressure
  regulator setpoints).
* ``set_point_by: operator`` — the operator is asked to set it and confirms (``confirm``
  callback; the CLI asks on the terminal).

Then a settling check: short unexcited records (``settle.hold_s``) are taken until the measured
``omega_rpm`` and ``p_inj_bar`` channels stay within tolerance of the target for a whole hold
window, or ``settle.timeout_s`` passes (the point is then marked ``not_settled``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from rigd.experiments.schemas import OperatingPoint, SettleSpec


def set_point(loop: Any, op: OperatingPoint, how: str,
              confirm: Callable[[str], bool] | None) -> None:
    """Bring the rig to ``op`` (see module docstring). Raises PointFailed if refused."""
    from rigd.experiments.points import PointFailed

    if how == "operator":
        if confirm is None:
            raise PointFailed("set_point_by: operator needs an operator (run on a terminal)")
        if not confirm(f"set Ω = {op.omega_rpm:g} rpm and P_I = {op.p_inj_bar:g} bar, "
                       "then confirm"):
            raise PointFailed("operator declined the operating point")
    # Always tell the loop: on the sim it sets the plant, on a rig it records the target.
    loop.set_operating_point(op.omega_rpm, op.p_inj_bar)


def settle_check(loop: Any, op: OperatingPoint, settle: SettleSpec, fs: float,
                 ) -> dict[str, Any]:
    """Wait until Ω and P_I are within tolerance for ``hold_s``; returns what was measured.

    Returns
    -------
    dict
        ``{"settled": bool, "omega_rpm": mean, "p_inj_bar": mean, "waited_s": s}``.
    """
    from rigd.experiments.points import SegmentFault
    from rigd.frame import REC

    n = max(1, int(round(settle.hold_s * fs)))
    t0 = time.monotonic()
    waited = 0.0
    result: dict[str, Any] = {"settled": False}
    while True:
        # in memory (the loop's process writes no HDF5: the writer process does, and this
        # short check needs no file)
        res = loop.run_segment(np.zeros((n, 2)), record="memory", stop_on_fault=True)
        if getattr(res, "fault", None):
            raise SegmentFault(res.fault, "the settling check")
        waited += n / fs
        fr = res.frames
        w, p = fr[:, REC["omega_rpm"]], fr[:, REC["p_inj_bar"]]
        ok = True
        for name, x, target, tol in (("omega_rpm", w, op.omega_rpm, settle.tolerance_rpm),
                                     ("p_inj_bar", p, op.p_inj_bar, settle.tolerance_bar)):
            if x is None or not np.isfinite(x).any():
                result[name] = None        # not measured: cannot check, do not block
                continue
            result[name] = float(np.nanmean(x))
            if np.nanmax(np.abs(x - target)) > tol:
                ok = False
        if ok:
            result.update(settled=True, waited_s=waited)
            return result
        if waited >= settle.timeout_s or time.monotonic() - t0 >= settle.timeout_s:
            result.update(settled=False, waited_s=waited)
            return result
