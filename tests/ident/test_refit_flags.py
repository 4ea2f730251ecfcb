"""Honest figures (issue 20, item 9): a refit worse than the model it extends, below 0 % or
diverged is flagged and never ranked (``diagnose``'s findings, ``identify --add``); a
compared fit below 0 % carries a warning (``compare``).

Records: the first-order heater with a transport delay of test_validation_figures (scipy,
independent of rigd's model classes).
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from rigd.diagnose import selection as S
from rigd.ident.figures import REFIT_FLAGS, fit_percent, refit_flag
from rigd.ident.workflow import identify_record
from tests.ident.test_validation_figures import heater


@pytest.mark.parametrize("fit_with, fit_base, flag", [
    (-np.inf, 50.0, "diverged"), (np.nan, 50.0, "diverged"), (-0.01, -20.0, "below_zero"),
    (-30.0, 50.0, "below_zero"), (49.99, 50.0, "worse_than_base"),
    (50.0, 50.0, None), (60.0, 50.0, None), (10.0, -np.inf, None)])
def test_refit_flag(fit_with, fit_base, flag):
    assert refit_flag(fit_with, fit_base) == flag
    assert flag is None or flag in REFIT_FLAGS


def _spoilt(monkeypatch, how: dict):
    """``refit_effect`` made to return, for the effects in ``how``, a simulation spoilt
    from the real refit's (``how[name](y, yhat) -> yhat``)."""
    real = S.refit_effect

    def fake(eff, ctx, sig, data_est, max_nfev, method="oe", kept=()):
        ref = real(eff, ctx, sig, data_est, max_nfev, method, kept)
        if eff.name not in how:
            return ref
        yw = how[eff.name](ctx.y, ctx.yhat)
        fw = float(np.mean(fit_percent(ctx.y[ctx.val], yw[ctx.val])))
        return S.Refit(ref.structure, ref.theta, yw, fw, ref.seconds, ref.fixed, ref.sig)

    monkeypatch.setattr(S, "refit_effect", fake)


@pytest.mark.parametrize("spoil, flag, words", [
    # a refit that lost fit (its error × 1.5 of the base's)
    (lambda y, yh: yh - 0.5 * (y - yh), "worse_than_base", "worse than the model it extends"),
    # a refit below 0 % (the output mirrored about its mean)
    (lambda y, yh: 2.0 * y.mean(axis=0) - y, "below_zero", "below 0 %")])
def test_diagnose_flags_refits_and_never_ranks_them(monkeypatch, tmp_path, spoil, flag,
                                                     words):
    """A Hammerstein record whose static nonlinearity is found when its refit is honest
    (test_generated_records); here its refit is spoilt: flagged, not significant, after
    every unflagged finding, said in the text; every other refit obeys the same rule."""
    from rigd.cli.diagnose import summary
    from rigd.diagnose.diagnosis import diagnose_record
    from tests.gen.nonlinear import hammerstein

    _spoilt(monkeypatch, {"static_nonlinearity": spoil})
    diag = diagnose_record(hammerstein(n=3000, seed=1).record(), order=2,
                           effects=["static_nonlinearity", "delay"], yardstick=False)
    sd = diag.parts[0]
    base = sd.steps[0].fit_percent
    assert len(sd.steps) == 1   # nothing added: the only strong effect was spoilt
    f = next(f for f in sd.findings if f.effect == "static_nonlinearity")
    assert f.evidence["refit_flag"] == flag and not f.significant
    assert f.fit_percent_with < (0.0 if flag == "below_zero" else base)
    for g in sd.findings:   # the rule, whatever the refit: flagged iff worse or below 0
        if "refit_seconds" in g.evidence:
            assert ("refit_flag" in g.evidence) == (g.fit_percent_with < max(base, 0.0))
    out = diag.to_json()
    flagged = ["refit_flag" in g for g in out["findings"]]
    assert flagged == sorted(flagged) and flagged[-1]
    assert next(g for g in out["findings"] if g["effect"] == "static_nonlinearity")[
        "refit_flag"] == flag
    json.loads(json.dumps(out, allow_nan=False))  # strict JSON: no -inf fit anywhere
    line = next(ln for ln in summary(out).splitlines()
                if "static_nonlinearity" in ln and "score" in ln)
    assert words in line and "not ranked" in line, line
    # the report's table says it too, beside every figure of the sub-model
    from rigd.diagnose.report_page import write_report

    write_report(diag, tmp_path / "rep")
    page = (tmp_path / "rep" / "figures.html").read_text()
    assert f"(flagged: {flag}, not ranked)" in page
    for fig in ("time", "spectrum", "amplitude", "resid"):
        assert (tmp_path / "rep" / f"generic_{fig}.png").is_file(), fig


def test_identify_add_warns_when_the_effects_made_the_fit_worse():
    from rigd.ident.workflow import _refit_warnings

    rec = heater(6)
    model = identify_record(rec, "generic", method="oe", order=1)
    sm = model.submodels["generic"]
    from rigd.ident.pipeline import FitSettings, fit_base

    bf = fit_base(rec, "generic", FitSettings(method="oe", order=1))
    fb = float(np.mean(sm.fit_percent["validation"]))
    other = SimpleNamespace()   # any structure that is not the base
    assert _refit_warnings(bf, bf.structure, np.array([fb - 5])) == []
    assert _refit_warnings(bf, other, np.array([fb + 1])) == []
    (w,) = _refit_warnings(bf, other, np.array([fb - 5]))
    assert f"{fb - 5:.2f} %" in w and f"{fb:.2f} %" in w and "worse than the model" in w
    (w,) = _refit_warnings(bf, other, np.array([-12.0]))
    assert "below 0 %" in w


def test_compare_warns_on_a_fit_below_zero(tmp_path, capsys):
    from rigd import api
    from rigd.cli import main
    from rigd.data.csvio import write_csv

    rec = heater(7)
    model = identify_record(rec, "generic", method="oe", order=1)
    ok = api.compare(model, rec)
    assert not [w for w in ok.warnings if "below 0 %" in w]
    y = rec.col("temp")
    bad = heater(7)
    bad.columns["temp"] = 2.0 * y.mean() - y   # the output mirrored: worse than its mean
    res = api.compare(model, bad)
    (w,) = [w for w in res.warnings if "below 0 %" in w]
    assert w.startswith("generic: temp: fit -") and float(np.mean(res.comparisons[
        "generic"].fit)) < 0
    path, mpath = tmp_path / "bad.csv", tmp_path / "m.yaml"
    write_csv(path, bad)
    model.save(mpath)
    assert main(["compare", str(mpath), str(path)]) == 0
    assert "below 0 %" in capsys.readouterr().out
