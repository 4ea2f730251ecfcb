"""An effect with costly fits (``Effect.max_fit_samples``: the restoring-force hysteresis's
RK4 refits) is fitted on a window of a long record's estimation part — never silently left
out — and says so: in the finding, in the terminal, and in ``rigd identify --add``, which
fits it on the same window (one pipeline). The window is made small here (1,500 of 4,000
estimation samples of a generated Bouc–Wen oscillator, tests/gen/nonlinear.py) so that the
behaviour shows at a test's cost; the shipped window is 10,000 samples."""

import pytest

from rigd import api
from rigd.cli import main
from rigd.effects import REGISTRY
from tests.gen import nonlinear

WINDOW = 1500


@pytest.fixture()
def small_window(monkeypatch):
    monkeypatch.setattr(REGISTRY["hysteresis_restoring"], "max_fit_samples", WINDOW)


@pytest.mark.timeout(1200)  # one default diagnosis and one identify --add, busy host
def test_a_long_record_fits_the_hysteresis_on_a_window_and_says_so(small_window, tmp_path,
                                                                     capsys, monkeypatch):
    g = nonlinear.bouc_wen(n=6000, seed=4)
    path = g.write_csv(tmp_path / "bw.csv")
    kw = {"fs": g.fs, "inputs": g.inputs, "outputs": g.outputs}
    res = api.diagnose(path, **kw)
    # the terminal: `rigd diagnose` prints this result (its whole CLI path, not fitted again)
    monkeypatch.setattr(api, "diagnose", lambda *a, **k: res)
    assert main(["diagnose", str(path), "--fs", str(g.fs), "--inputs", *g.inputs,
                 "--outputs", *g.outputs]) == 0
    text = capsys.readouterr().out
    note = f"hysteresis_restoring fitted on the first {WINDOW} of the 4000 estimation samples"
    assert any(ln.lstrip().startswith("note: ") and note in ln for ln in text.splitlines()), text
    d = res.summary()
    f = res.diagnosis.parts[0].findings[0]
    assert f.effect == "hysteresis_restoring" and f.evidence["fitted_on_samples"] == [WINDOW,
                                                                                      4000]
    hyst = d["findings"][0]
    # the behaviour shows on the window: named first, the held-out error (on the whole
    # validation part) cut at least 2×
    assert hyst["significant"] and hyst.get("site") == "restoring force", d["findings"][:3]
    assert 100 - d["fit_percent"] >= 2 * (100 - hyst["fit_percent_with"])
    # identify --add fits it on the same window, says so, and gives diagnose's fit
    idf = api.identify(path, add=["hysteresis_restoring"], yardstick=False, **kw)
    sub = next(iter(idf.model.submodels.values()))
    assert any(note in w for w in sub.readouts.get("warnings", [])), sub.readouts
    assert sub.fit_percent["validation_mean"] == pytest.approx(hyst["fit_percent_with"],
                                                               abs=0.05)


def test_the_window_is_the_first_samples_of_the_estimation_part(small_window):
    import numpy as np

    from rigd.diagnose.selection import fit_window
    from rigd.ident.pipeline import prepare

    data, _ = prepare(nonlinear.bouc_wen(n=2000, seed=4).record(), "generic")
    eff = REGISTRY["hysteresis_restoring"]
    cut, window = fit_window(eff, data)
    assert window == (WINDOW, 2000) and cut.n == WINDOW
    assert np.array_equal(cut.y, data.y[:WINDOW]) and np.array_equal(cut.u, data.u[:WINDOW])
    short = data.slice(0, WINDOW)
    assert fit_window(eff, short) == (short, None)        # within the window: whole
    assert fit_window(REGISTRY["cubic_stiffness"], data) == (data, None)   # no window
