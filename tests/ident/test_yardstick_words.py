"""The yardstick's words: a reference below 0 % on the held-out part (a subspace model
unstable there printed "-1949 %") is said to be no measure, and it is not the best one the
model is compared with."""

import numpy as np

from rigd.ident.yardstick import Reference, Yardstick


def _ref(name, fit):
    detail = {"order": 8} if name == "subspace" else {"order": 10, "delays_samples": [0]}
    return Reference(name, fit, [fit], detail, np.zeros((4, 1)))


def test_a_reference_below_zero_is_remarked_and_not_the_yardstick():
    ys = Yardstick(73.7, [_ref("arx", 25.0), _ref("subspace", -1949.0)])
    text = ys.describe()
    sub = text[text.index("subspace"):]
    assert "-1949.00 %" in sub and "does not hold on the held-out part" in sub
    assert "does not hold" not in text[:text.index("subspace")]     # ARX at 25 % is fine
    assert ys.best.name == "arx" and not ys.worse


def test_only_references_below_zero_leave_no_yardstick():
    ys = Yardstick(10.0, [_ref("subspace", -5.0)])
    assert ys.best is None and ys.gap == 0.0 and ys.warning() is None
    assert ys.reachable(10.0) is None


def test_a_reference_above_the_model_still_warns():
    ys = Yardstick(60.0, [_ref("arx", 80.0), _ref("subspace", -3.0)])
    assert ys.worse and "80.00 %" in ys.warning()
