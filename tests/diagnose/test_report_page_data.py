"""The data of the interactive compare / diagnose pages (rigd/htmlpage.py,
rigd/diagnose/{page_data,compare_page,diagnose_page}.py): what the page shows is what
``diagnose`` and ``compare`` computed, the embedded JSON is strict (no NaN), long records are
decimated keeping their peaks, resonances are marked only below Nyquist, and the report folder
refers to nothing outside itself.

Records are generated here: a Duffing oscillator (tests/diagnose/benchmarks.py, generic, where
diagnose adds cubic_stiffness) and a simulated rotor with run-out (tests/ident/ident_helpers.py,
with the shaft angle φ).
"""

import json
import re
import sys
from pathlib import Path

import benchmarks as B  # tests/diagnose/benchmarks.py
import numpy as np
import pytest

from rigd import api
from rigd.diagnose.diagnose_page import unexplained_marks
from rigd.diagnose.page_data import model_view, resonances_below_nyquist
from rigd.htmlpage import json_safe, minmax_decimate, page_json

sys.path.insert(0, str(Path(__file__).parents[1] / "ident"))
from ident_helpers import rotor_record  # noqa: E402


def _strict(text: str):
    """json.loads that refuses NaN / Infinity (what a browser's JSON.parse refuses)."""
    def bad(c):
        raise ValueError(f"non-JSON constant {c}")
    return json.loads(text, parse_constant=bad)


def embedded(index: Path) -> dict:
    """The page data embedded in ``index.html``, parsed strictly."""
    html = index.read_text(encoding="utf-8")
    m = re.search(r"<script type='application/json' id='page-data'>(.*?)</script>", html, re.S)
    assert m, "no page data in the page"
    return _strict(m.group(1))


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    out = tmp_path_factory.mktemp("diag")
    res = api.diagnose(B.duffing(seed=3, n=3000), effects="cubic_stiffness,delay", order=2,
                       report=out)
    return res, out


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp")
    idf = api.identify(rotor_record(n=4000, seed=11, omega_rpm=3000, runout=1.0), "bearing")
    res = api.compare(idf, rotor_record(n=4000, seed=12, omega_rpm=3000, runout=1.0),
                      report=out)
    return res, out


def test_diagnose_page_steps_are_diagnose_numbers(diagnosed):
    res, out = diagnosed
    js = res.summary()
    assert js["report"] == str(out / "index.html")
    data = embedded(out / "index.html")
    assert data["kind"] == "diagnose"
    (part,) = data["parts"]
    sd = res.diagnosis.parts[0]
    # the forward selection added cubic_stiffness: base and one step, as --json says
    assert [s["added"] for s in part["steps"]] == [s["added"] for s in js["steps"]] \
        == [None, "cubic_stiffness"]
    for s, jstep, st in zip(part["steps"], js["steps"], sd.steps):
        v = part["variants"][s["variant"]]
        assert s["fit_percent"] == pytest.approx(st.fit_percent, abs=1e-3)
        assert s["fit_percent"] == pytest.approx(jstep["fit_percent"], abs=1e-3)
        # the variant's fit is recomputed from its simulated output: the same number
        assert v["fit_percent"] == pytest.approx(st.fit_percent, abs=1e-3)
        assert v["error_percent"] == pytest.approx(100 - st.fit_percent, abs=1e-3)
    assert part["steps"][1]["error_before"] == pytest.approx(100 - sd.steps[0].fit_percent)
    # every tested effect with a refit is a toggle, with its fit as diagnose reports it
    fw = {f["effect"]: f["fit_percent_with"] for f in js["findings"]}
    by_set = {frozenset(v["effects"]): v for v in part["variants"]}
    assert frozenset() in by_set and frozenset({"cubic_stiffness"}) in by_set
    assert by_set[frozenset({"cubic_stiffness", "delay"})]["fit_percent"] == \
        pytest.approx(fw["delay"], abs=1e-3)
    assert {e["name"] for e in part["effects"] if e["toggle"]} == {"cubic_stiffness", "delay"}
    assert by_set[frozenset()]["fit_percent"] < by_set[frozenset({"cubic_stiffness"})][
        "fit_percent"] - 10


def test_diagnose_page_views_and_files(diagnosed):
    res, out = diagnosed
    part = embedded(out / "index.html")["parts"][0]
    fs = part["fs"]
    assert part["peaks_hz"] and all(0 < f < fs / 2 for f in part["peaks_hz"])
    assert part["peaks_hz"][0] == pytest.approx(60, rel=0.1)   # f_n of the benchmark
    for v in part["variants"]:
        assert len(v["traces"][0]["x"]) <= 2000 and len(v["spectrum"]["f"]) > 10
        assert v["angle"] is None            # no shaft angle in this record
    # every unexplained frequency band diagnose reported is marked on the spectrum
    bands = [u["where"]["band_hz"] for u in res.summary()["unexplained"]
             if "band_hz" in u["where"]]
    got = [v for m in part["marks"] if m["kind"] == "band" for v in (m["lo"], m["hi"])]
    assert got == pytest.approx([v for lo, hi in bands for v in (lo, min(hi, fs / 2))])
    # the PNGs stay (papers) beside their own page; the interactive page names them
    data = embedded(out / "index.html")
    assert data["figures"] and all((out / f).is_file() for f in data["figures"])
    assert (out / "figures.html").is_file()
    html = (out / "index.html").read_text()
    # self-contained: no script or style from elsewhere; apart from plotly's bundle nothing
    # names a URL scheme or a path of this machine (so it works served over HTTP too)
    assert not re.search(r"<script[^>]+src=", html) and "<link rel='stylesheet'" not in html
    own = re.sub(r"<script>.*?</script></head>", "", html, count=1, flags=re.S)
    assert len(own) < len(html) / 10              # the bundle was the part removed
    assert str(out) not in own and "/tmp/" not in own
    assert not re.search(r"(file|https?)://", own)


def test_compare_page_has_polar_spectrum_and_the_fit(compared):
    res, out = compared
    data = embedded(out / "index.html")
    assert data["kind"] == "compare"
    (part,) = data["parts"]
    c = res.comparisons["bearing"]
    v = part["variants"][0]
    assert v["fit_per_output"] == pytest.approx(list(c.fit), abs=1e-3)
    assert [r["fit_percent"] for r in part["table"]] == pytest.approx(list(c.fit), abs=1e-3)
    # φ in the record: mean residual by angle, one curve per output; the run-out (1 µm at
    # 1×) the bearing model does not have shows as a clear first harmonic of the angle
    ang = v["angle"]
    assert ang is not None and len(ang["deg"]) == 36 and len(ang["mean"]) == 2
    mx = np.asarray(ang["mean"][0])
    assert np.ptp(mx) > 1.0
    assert part["peaks_hz"] and all(0 < f < part["fs"] / 2 for f in part["peaks_hz"])
    assert "bearing_bode.png" in data["figures"]


def test_resonances_above_nyquist_are_not_marked():
    assert resonances_below_nyquist([2600.0, 0.0, 120.0, 2499.0, 7e3], 5000.0) == \
        [120.0, 2499.0]


def test_json_is_strict_and_cannot_close_the_script():
    data = {"a": np.array([1.0, np.nan, np.inf, -np.inf]), "b": float("nan"),
            "s": "</script><script>alert(1)</script>", "n": np.int64(3),
            "p": Path("x.png"), "t": (np.float32(0.1234567891), True)}
    text = page_json(data)
    assert "</" not in text and "NaN" not in text and "Infinity" not in text
    back = _strict(text)
    assert back["a"] == [1.0, None, None, None] and back["b"] is None
    assert back["s"] == data["s"] and back["n"] == 3 and back["p"] == "x.png"
    assert back["t"] == [pytest.approx(0.123457), True]
    assert json_safe(np.zeros(0)) == []


def test_minmax_decimation_keeps_every_peak_and_order():
    rng = np.random.default_rng(0)
    n = 100_000
    t = np.arange(n) / 1e4
    y = rng.standard_normal(n)
    spikes = rng.choice(n, 25, replace=False)
    y[spikes] = 50.0 + np.arange(25)            # isolated peaks a subsample would drop
    y[7] = -80.0
    x2, y2 = minmax_decimate(t, y, 2000)
    assert len(x2) <= 2000 and np.all(np.diff(x2) > 0)
    assert set(np.round(t[spikes], 6)) <= set(np.round(x2, 6))
    assert y2.min() == -80.0 and y2.max() == y.max()
    # short records are kept whole
    x3, y3 = minmax_decimate(t[:500], y[:500], 2000)
    assert np.array_equal(y3, y[:500])


def test_model_view_with_nan_free_output_and_angle():
    fs, n = 1000.0, 4000
    t = np.arange(n) / fs
    phi = np.mod(2 * np.pi * 25 * t, 2 * np.pi)
    y = np.column_stack([np.sin(2 * np.pi * 7 * t), np.cos(2 * np.pi * 3 * t)])
    yhat = y - 0.2 * np.column_stack([np.cos(phi), np.zeros(n)])
    v = model_view(t, y, yhat, fs, slice(0, n), phi)
    deg, mean = v["angle"]["deg"], v["angle"]["mean"]
    # the mean residual by angle is the 0.2·cos φ put in
    assert np.allclose(mean[0], 0.2 * np.cos(np.radians(deg)), atol=0.02)
    assert np.allclose(mean[1], 0.0)
    text = page_json(v)
    assert _strict(text)["fit_per_output"][1] == pytest.approx(100.0)


@pytest.mark.parametrize("mask", [0o022, 0o027])
def test_page_is_written_atomically_with_the_callers_umask(tmp_path, mask):
    import os
    import stat

    from rigd.htmlpage import write_page

    old = os.umask(mask)
    try:
        page = write_page(tmp_path / "rep", "t", {"kind": "compare", "parts": []})
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(page).st_mode) == 0o666 & ~mask
    assert [p.name for p in page.parent.iterdir()] == ["index.html"]   # no temporary left
    # a page whose data cannot be made JSON leaves the previous page whole
    with pytest.raises(ValueError):
        write_page(tmp_path / "rep", "t", {"x": object.__new__(_Unjsonable)})
    assert embedded(page) == {"kind": "compare", "parts": []}
    assert [p.name for p in page.parent.iterdir()] == ["index.html"]


class _Unjsonable:
    def __str__(self):
        raise ValueError("cannot be shown")


def test_a_bad_report_folder_is_one_line_exit_2_before_any_work(tmp_path, capsys):
    from rigd.cli import main
    from rigd.data.csvio import write_csv

    write_csv(tmp_path / "duffing.csv", B.duffing(seed=1, n=600))
    blocker = tmp_path / "a_file"
    blocker.write_text("keep me")
    for argv in (["diagnose", str(tmp_path / "duffing.csv"), "--order", "1"],
                 ["compare", str(tmp_path / "no_model.yaml"), str(tmp_path / "duffing.csv")]):
        assert main(argv + ["--report", str(blocker)]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "--report" in err and "a_file" in err and "folder" in err
        # a folder below a file cannot be made either
        assert main(argv + ["--report", str(blocker / "rep")]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "--report" in err
    assert blocker.read_text() == "keep me"


def test_diagnose_page_without_refits_has_only_the_base_model(tmp_path):
    res = api.diagnose(B.duffing(seed=2, n=1500), effects="cubic_stiffness", order=2,
                       refit=False, report=tmp_path / "rep")
    (part,) = embedded(tmp_path / "rep" / "index.html")["parts"]
    assert len(part["variants"]) == 1 and part["variants"][0]["effects"] == []
    assert not any(e["toggle"] for e in part["effects"])
    assert part["steps"][0]["fit_percent"] == pytest.approx(
        res.summary()["fit_percent"], abs=1e-3)


def test_unexplained_places_become_marks_in_the_page_time_base():
    unexpl = [{"where": {"residual": "structured"}, "text": "structured: where ..."},
              {"where": {"frequency_hz": 122.0, "band_hz": [121.8, 145.4]},
               "text": "11 % of the error energy lies in 121.78–145.4 Hz: a mode"},
              {"where": {"band_hz": [200.0, 400.0]}, "text": "up to above Nyquist: x"},
              {"where": {"samples": [5000, 6000], "time_s": [5.0, 6.0]},
               "text": "51 % of the error energy lies in samples 5000..6000: a change"},
              {"where": {"samples": [100, 900]}, "text": "before the window: y"}]
    # the analysed window starts at sample 4000 of the record, 3000 samples at 1 kHz
    marks = unexplained_marks(unexpl, (4000, 7000), 1000.0, 3000)
    assert marks == [
        {"kind": "band", "lo": 121.8, "hi": 145.4,
         "text": "11 % of the error energy lies in 121.78–145.4 Hz"},
        {"kind": "band", "lo": 200.0, "hi": 400.0, "text": "up to above Nyquist"},
        {"kind": "time", "t0": 1.0, "t1": 2.0,
         "text": "51 % of the error energy lies in samples 5000..6000"}]
    assert unexplained_marks(unexpl[2:3], (0, 700), 700.0, 700)[0]["hi"] == 350.0
