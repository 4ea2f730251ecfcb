"""Silverbox (measured, not made by this project) and the CLI contract."""

import json

import numpy as np
import pytest
from testpaths import ROOT

from rigd.cli import main
from rigd.diagnose import residual as R


# make test-long (CI): in make test the README's Silverbox commands (tests/test_readme_commands.py)
# show the default diagnosis adding cubic stiffness alone and the arrow's error falling
@pytest.mark.long
def test_silverbox_cubic_first_and_error_halved(capsys, tmp_path):
    """Estimated on 12,000 samples of the multisine part (20 s; the whole part, 91,000
    samples, names the same at several times the cost), validated on the arrow (the first
    40,000 samples, amplitude rising past the multisine's): the error falls ~10× with cubic
    stiffness (≥ 2× asserted; 12,000 other multisine samples give ~6× on the arrow's first
    half)."""
    path = ROOT / "examples" / "data" / "silverbox.csv.gz"   # SNLS80mV, shipped
    rc = main(["diagnose", str(path), "--fs", "610.3515625", "--inputs", "V1", "--outputs", "V2",
               "--est", "40600:52600", "--val", "0:40000", "--json", "--report", str(tmp_path)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    top = out["findings"][0]
    assert top["effect"] == "cubic_stiffness" and top["significant"]
    assert (100 - out["fit_percent"]) >= 2 * (100 - top["fit_percent_with"])
    # forward selection: once cubic stiffness is in, nothing else is significant
    assert [f["effect"] for f in out["findings"] if f["significant"]] == ["cubic_stiffness"]
    assert [s["added"] for s in out["steps"]] == [None, "cubic_stiffness"]
    assert out["steps"][0]["fit_percent"] == out["fit_percent"]
    assert out["steps"][1]["fit_percent"] == top["fit_percent_with"]
    cannot = {c["effect"] for c in out["cannot_reveal"]}
    assert "cross_coupling" in cannot
    # nothing turns in this circuit: run-out is not offered (no rotor advice), and said so
    assert "runout" not in cannot
    assert any("runout not offered: " in n and "nothing in the record turns" in n
               for n in out["notes"]), out["notes"]
    assert (tmp_path / "index.html").exists()


def test_cli_unknown_effect_is_one_line_exit_2(capsys, tmp_path):
    p = tmp_path / "x.csv"
    p.write_text("a,b\n1,2\n")
    rc = main(["diagnose", str(p), "--effects", "nonsense"])
    err = capsys.readouterr().err
    assert rc == 2 and "unknown effect" in err and err.count("\n") == 1


def test_whiteness_and_cross_correlation_bounds():
    rng = np.random.default_rng(0)
    e = rng.standard_normal(20000)
    assert R.whiteness(e).passed
    col = np.convolve(e, np.ones(10) / 10, mode="same")
    assert not R.whiteness(col).passed
    u = rng.standard_normal(20000)
    assert R.cross_correlation(e, u).outside < 0.1
    r = np.r_[np.zeros(3), u[:-3]] + 0.5 * e  # residual driven by the input 3 samples late
    c = R.cross_correlation(r, u)
    assert np.abs(c.rho).max() > 10 * c.bound and c.lags[np.argmax(np.abs(c.rho))] in (3, -3)


# make test-long (CI): in make test the README's Silverbox commands (tests/test_readme_commands.py)
# print identify's and diagnose's base fits, each compared with the README's figure
@pytest.mark.long
def test_identify_and_diagnose_give_the_same_base_fit(capsys):
    """One hold convention and one split: `rigd identify --method oe` and `rigd diagnose`
    report the same validation fit of the base model on the same samples."""
    path = ROOT / "examples" / "data" / "silverbox.csv.gz"   # SNLS80mV, shipped
    common = [str(path), "--fs", "610.3515625", "--inputs", "V1", "--outputs", "V2",
              "--range", "40600:58600", "--json"]
    assert main(["identify", *common, "--method", "oe"]) == 0
    ident = json.loads(capsys.readouterr().out)
    assert main(["diagnose", *common, "--effects", "delay"]) == 0
    diag = json.loads(capsys.readouterr().out)
    assert ident["split"]["estimation"] == [0, 12000]
    assert abs(ident["fit_percent"] - diag["fit_percent"]) < 1e-3, (ident["fit_percent"],
                                                                    diag["fit_percent"])
