"""The README's demo figures cannot drift: the seeded demo (what `make demo` runs) is rerun
and every figure between the README's demo-table markers must be within 2 % of what
tools/readme_demo_table.py renders from the fresh demo-out/summary.json. The demo's own
contract (the issue's must-show figures) is checked on the same run."""

import json
import sys
import warnings

import pytest
from testpaths import ROOT

from rigd.cli import main

sys.path.insert(0, str(ROOT / "tools"))
import readme_demo_table as tool  # noqa: E402

# the whole seeded demo runs in the first test's setup: minutes of CPU, and `make test` runs
# this part at `nice` beside the timing tests (and beside `under-load`'s busy loops it got
# a tenth of a core: the 600 s hang guard fired in the demo's structured design)
pytestmark = pytest.mark.timeout(2400)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "demo-out"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["demo", "--out", str(out)]) == 0
    return json.loads((out / "summary.json").read_text()), caught


@pytest.fixture(scope="module")
def summary(demo):
    return demo[0]


def test_demo_path_has_no_numerical_warnings(demo):
    """No LinAlgWarning (the Tustin of the 32-state K warned rcond = 1.9e-19), no
    RuntimeWarning (overflow, division), no ComplexWarning, no matplotlib slow-legend warning
    on the whole `make demo` path."""
    from numpy.exceptions import ComplexWarning
    from scipy.linalg import LinAlgWarning

    bad = [f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in demo[1]
           if issubclass(w.category, (LinAlgWarning, RuntimeWarning, ComplexWarning,
                                      UserWarning))]
    assert not bad, bad


def test_tool_detects_a_drifted_figure(tmp_path):
    s = {"damping_ratio_open": {f"P{p}bar_W0rpm_{a}": 0.05 for p in (4, 7) for a in "xy"},
         "damping_ratio_closed": {f"P{p}bar_W0rpm_{a}": 0.2 for p in (4, 7) for a in "xy"},
         "damping_increase": {f"P{p}bar_W0rpm_{a}": 4.0 for p in (4, 7) for a in "xy"},
         "design_method": "structured", "controller_order": 4, "gamma": 2.0,
         "robustness": {"n_realizations": 30, "all_stable": True, "sensitivity_peak_max": 1.8,
                        "sensitivity_peak_hz": 300.0}}
    readme = f"x\n{tool.BEGIN}\n{tool.render(s)}\n{tool.END}\ny"
    assert tool.compare(readme, s) == []
    s2 = json.loads(json.dumps(s))
    s2["robustness"]["sensitivity_peak_max"] = 1.8 * 1.03
    assert len(tool.compare(readme, s2)) == 1
    s2["robustness"]["sensitivity_peak_max"] = 1.8 * 1.01       # within 2 %: not a drift
    assert tool.compare(readme, s2) == []
    assert tool.rewrite(readme, s2).startswith("x\n" + tool.BEGIN)
    assert tool.compare(tool.rewrite(readme, s2), s2) == []


def test_readme_demo_table_matches_the_demo(summary):
    drift = tool.compare((ROOT / "README.md").read_text(), summary)
    assert not drift, "README demo figures drifted (run `make demo` and " \
        "`python tools/readme_demo_table.py`): " + "; ".join(drift)


def test_demo_meets_the_design_targets(summary):
    s = summary
    r = s["robustness"]
    assert s["controller_order"] <= 6 and s["design_method"] == "structured"
    assert r["n_realizations"] == 30 and r["all_stable"]
    assert s["sensitivity_peak_max"] <= 2.0
    assert s["disturbance_peak_reduction_min"] >= 3.0
    assert s["sensitivity_reduction_at_resonance_mode_direction_min"] >= 3.0
    assert s["sensitivity_lowfreq_max"] <= 1.3
    inc = s["damping_increase"]
    for ax in "xy":
        assert inc[f"P4bar_W0rpm_{ax}"] >= 3.0
        assert inc[f"P7bar_W0rpm_{ax}"] >= 4.0


def test_tool_renders_the_diagnosis_and_detects_its_drift():
    s = {"damping_ratio_open": {f"P{p}bar_W0rpm_{a}": 0.05 for p in (4, 7) for a in "xy"},
         "damping_ratio_closed": {f"P{p}bar_W0rpm_{a}": 0.2 for p in (4, 7) for a in "xy"},
         "damping_increase": {f"P{p}bar_W0rpm_{a}": 4.0 for p in (4, 7) for a in "xy"},
         "design_method": "structured", "controller_order": 4, "gamma": 2.0,
         "robustness": {"n_realizations": 30, "all_stable": True},
         "diagnosis": {"named": ["actuator_dynamics"],
                       "named_by_submodel": {"actuator": [], "bearing": ["actuator_dynamics"]},
                       "fit_before": {"actuator": 97.5, "bearing": 68.2},
                       "fit_after": {"actuator": 97.5, "bearing": 93.1}}}
    text = tool.render(s)
    assert "| bearing | `actuator_dynamics` | 68.20 % | 93.10 % | 31.80 → 6.90 |" in text
    assert "| actuator | nothing |" in text
    readme = f"{tool.BEGIN}\n{text}\n{tool.END}"
    s["diagnosis"]["fit_after"]["bearing"] = 90.0
    assert tool.compare(readme, s)


def test_default_demo_diagnoses_and_the_held_out_error_falls(summary):
    """Issue 23's must-show on `rigd demo` with its defaults (the physics-grade plant): the
    diagnosis names something and the held-out fit rises where it did."""
    d = summary["diagnosis"]
    assert summary["plant"] == "sim_reynolds"
    assert d["named"], d
    for sub, names in d["named_by_submodel"].items():
        if names:
            assert d["fit_after"][sub] > d["fit_before"][sub], sub
