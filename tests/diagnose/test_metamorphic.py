"""Metamorphic tests: the same samples in other units must give the same diagnosis
(findings, significance, order) and the same fits (±0.1 point)."""

import benchmarks as B  # tests/diagnose/benchmarks.py
import pytest

from rigd.data.record import Record
from rigd.diagnose.diagnosis import diagnose_record


def _variant(rec, su=1.0, sy=1.0, sr=1.0):
    u, y = rec.inputs[0], rec.outputs[0]
    return Record({u: rec.col(u) * su, y: rec.col(y) * sy}, rec.fs * sr, dict(rec.meta),
                  "<variant>")


def _digest(d):
    out = d.to_json()
    return (out["fit_percent"], [(s["added"], s["fit_percent"]) for s in out["steps"]],
            out["order"]["generic"]["modes"])


def _same(a, b):
    assert a[2] == b[2], (a, b)
    assert [s for s, _ in a[1]] == [s for s, _ in b[1]], (a, b)
    assert abs(a[0] - b[0]) <= 0.1
    assert all(abs(x - y) <= 0.1 for (_, x), (_, y) in zip(a[1], b[1])), (a, b)


@pytest.fixture(scope="module")
def duffing():
    rec = B.duffing(seed=0, n=3000)
    return rec, _digest(diagnose_record(rec))


@pytest.mark.parametrize("scales", [dict(sy=1e-6), dict(su=1e3), dict(su=1e-6, sy=1e3)])
def test_duffing_channels_rescaled_same_diagnosis(duffing, scales):
    rec, ref = duffing
    assert [s for s, _ in ref[1]] == [None, "cubic_stiffness"]
    _same(ref, _digest(diagnose_record(_variant(rec, **scales))))


@pytest.mark.xfail(strict=True, reason="not invariant yet: creep's time-constant grid and "
                   "hold rule are in seconds (valve physics), extra_mode's spectral segment "
                   "length follows fs: at fs x 1e-3 creep, at fs x 1e3 extra_mode become "
                   "significant on this Duffing record (docs/diagnose.md, Limits)")
@pytest.mark.parametrize("rate", [1e-3, 1e3])
def test_duffing_rate_rescaled_same_diagnosis(duffing, rate):
    rec, ref = duffing
    _same(ref, _digest(diagnose_record(_variant(rec, sr=rate))))
