"""Unexplained measured against what is reachable (issue 20, item 7): the gap between rigd's
model and black-box references on the same split (rigd.ident.yardstick) counts as
structure; a badly fitting model is never "nothing unexplained"."""

from __future__ import annotations

import numpy as np

from rigd.diagnose import unexplained as U
from tests.gen import linear

PASSED = {"whiteness": {"y": {"passed": True, "outside": 0.0}},
          "cross_correlation": {"y~u": {"passed": True, "outside": 0.0}}}


def test_a_fast_response_is_not_noise_when_a_reference_reaches_it():
    """A residual near the Nyquist frequency looks like white noise to the difference-based
    estimate (and here the correlation tests are given as passed): alone it reports
    nothing; a reference model whose residual is 20× smaller makes it structure."""
    rng = np.random.default_rng(0)
    n = 4000
    k = np.arange(n)
    y = np.sin(2 * np.pi * 0.01 * k)[:, None]
    r = (0.3 * np.sin(2 * np.pi * 0.45 * k + 0.2)
         + 0.3 * np.sin(2 * np.pi * 0.41 * k))[:, None] + 0.01 * rng.standard_normal((n, 1))
    u = rng.standard_normal((n, 1))
    assert U.report(r, y + r, y, u, 1.0, PASSED, [], ["y"], ["u"]) == []
    ref = {"residual": r / 20.0, "fit": 95.0, "model_fit": 40.0, "label": "a plain ARX"}
    out = U.report(r, y + r, y, u, 1.0, PASSED, [], ["y"], ["u"], reference=ref)
    assert out and out[0]["where"]["residual"] == "structured"
    assert "a plain ARX reaches 95.00 %" in out[0]["text"]
    assert out[0]["share"] > 0.9


def test_too_low_an_order_is_never_nothing_unexplained():
    """A 3-mode structure (simulated independently, tests/gen) diagnosed with one mode:
    the base fits badly; the yardstick's references reach far more on the same split, the
    model is flagged worse, and the structure is reported unexplained."""
    from rigd import api
    from rigd.data.record import Record

    g = linear.structure([(0.8, 0.03), (2.1, 0.02), (3.7, 0.03)], 1, 1, fs=20.0, n=3000,
                         seed=5)
    rec = Record({"force1": g.u[:, 0], "disp1": g.y[:, 0]}, g.fs,
                 {"inputs": ["force1"], "outputs": ["disp1"]}, "<3 modes>")
    out = api.diagnose(rec, order=1, refit=False).summary()
    ys = out["yardstick"]["generic"]
    assert out["fit_percent"] < 60.0, out["fit_percent"]
    assert ys["model_worse"] and ys["gap_points"] > 20.0, ys
    assert max(ys["arx"]["fit_percent"], ys["subspace"]["fit_percent"]) > 90.0, ys
    assert out["unexplained"], out["tests"]
    head = out["unexplained"][0]
    assert head["where"]["residual"] == "structured" and head["share"] > 0.5, head
    assert "on the same split" in head["text"]
    assert any("WARNING" in n and "below a plain" in n for n in out["notes"]), out["notes"]
    lev = out["tests"]["generic"]["final_model"]["level"]
    assert lev["reachable_fit_points"] > 20.0, lev
