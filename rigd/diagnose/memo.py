"""Refits already done within one sub-model's diagnosis, kept and handed back.

A diagnosis runs the forward selection more than once from the same base (rigd.diagnose.
diagnosis: another linear candidate is diagnosed over the effects first added, and the one
kept is then diagnosed over the whole catalogue): the same effect refitted on the same model
(same structure object, parameters, data, split and settings) gives the same fit, so it is
fitted once. The same holds for a step's model refitted with the other input hold.
"""

from __future__ import annotations

import copy
import hashlib
from typing import Any

import numpy as np


def _slice_key(s: slice) -> tuple:
    return (s.start, s.stop, s.step)


class RefitMemo:
    """Results of :func:`rigd.diagnose.selection.refit_effect` and
    :func:`rigd.diagnose.selection.try_hold` by what decides them (module docstring)."""

    def __init__(self) -> None:
        self._done: dict[tuple, tuple[Any, Any]] = {}
        self._digests: dict[int, tuple[Any, str]] = {}

    def _digest(self, data) -> str:
        """Content digest of an IdData (u, y, rate), once per object."""
        hit = self._digests.get(id(data))
        if hit is not None and hit[0] is data:
            return hit[1]
        h = hashlib.blake2b(digest_size=16)
        for a in (data.u, data.y):
            a = np.ascontiguousarray(a, dtype=float)
            h.update(repr(a.shape).encode())
            h.update(a.tobytes())
        h.update(repr(float(data.fs)).encode())
        self._digests[id(data)] = (data, h.hexdigest())
        return self._digests[id(data)][1]

    def _get(self, key: tuple, structure):
        hit = self._done.get(key)
        if hit is None or hit[0] is not structure:
            return None
        return copy.copy(hit[1])

    def refit(self, fn, eff, ctx, sig, data_est, max_nfev, method: str, kept: tuple):
        """``fn(eff, ctx, sig, data_est, max_nfev, method, kept)`` (refit_effect), or the
        same refit done before on this model (a copy of it)."""
        key = ("refit", eff.name, id(ctx.structure),
               np.asarray(ctx.theta, float).tobytes(), self._digest(ctx.data),
               self._digest(data_est), _slice_key(ctx.est), _slice_key(ctx.val), max_nfev,
               method, tuple(kept))
        got = self._get(key, ctx.structure)
        if got is None:
            got = fn(eff, ctx, sig, data_est, max_nfev, method, kept)
            self._done[key] = (ctx.structure, got)
            got = copy.copy(got)
        return got

    def try_hold(self, fn, step, ctx0, hold: str, data_est, method: str):
        """``fn(step, ctx0, hold, data_est, method)`` (try_hold), or the same done before."""
        key = ("hold", id(step.structure), np.asarray(step.theta, float).tobytes(),
               tuple(step.fixed), float(step.fit_percent), hold, self._digest(ctx0.data),
               self._digest(data_est), _slice_key(ctx0.val), method)
        hit = self._done.get(key)
        if hit is not None and hit[0] is step.structure:
            return copy.copy(hit[1])
        got = fn(step, ctx0, hold, data_est, method)
        self._done[key] = (step.structure, got)
        return copy.copy(got)
