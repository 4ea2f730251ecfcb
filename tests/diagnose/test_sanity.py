"""Sanity of fitted models and of the modelling commands' input (issue 12, 'Sanity')."""

import json

import benchmarks as B  # tests/diagnose/benchmarks.py
import numpy as np
import pytest

from rigd.cli import main
from rigd.ident.mechanical import generic_structure
from rigd.ident.sanity import model_warnings


def test_unstable_mode_and_parameter_at_bound_are_named():
    st = generic_structure(["u"], ["y"], hold="foh")
    w = 2 * np.pi * 10.0
    stable = st.pack(np.array([[w * w]]), np.array([[0.1 * w]]), np.array([[1.0]]))
    unstable = st.pack(np.array([[w * w]]), np.array([[-0.035 * w]]), np.array([[1.0]]))
    assert model_warnings(st, stable) == []
    msg = model_warnings(st, unstable)
    assert len(msg) == 1 and "unstable mode" in msg[0] and "10 Hz" in msg[0]
    assert "-0.0175" in msg[0]

    class Bounded:
        names = ["a", "b"]

        def bounds(self):
            return np.array([0.0, -1.0]), np.array([1.0, 1.0])

    msg = model_warnings(Bounded(), np.array([1.0, 0.2]))
    assert len(msg) == 1 and "parameter a" in msg[0] and "bound" in msg[0]


def _csv(path, rec, scale=1.0):
    u, y = rec.inputs[0], rec.outputs[0]
    np.savetxt(path, np.column_stack([rec.col(u), scale * rec.col(y)]), delimiter=",",
               header=f"{u},{y}", comments="")
    return ["--fs", str(rec.fs), "--inputs", u, "--outputs", y]


def test_duplicate_add_is_refused_in_one_line(tmp_path, capsys):
    opts = _csv(tmp_path / "d.csv", B.duffing(seed=0, n=1500))
    rc = main(["identify", str(tmp_path / "d.csv"), *opts, "--add",
               "extra_mode,extra_mode", "-o", str(tmp_path / "m.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and "extra_mode given more than once" in err and err.count("\n") == 1
    assert not (tmp_path / "m.yaml").exists()


def test_compare_cubic_model_on_metres_and_millimetres(tmp_path, capsys):
    """The same record in m and in mm: compare works on both and gives the same fit (the
    initial state was estimated by stepping x0 by 1.0, i.e. 1 m, which diverged)."""
    rec = B.duffing(seed=1, n=3000)
    fits = []
    for name, scale in (("m", 1e-3), ("mm", 1.0)):
        opts = _csv(tmp_path / f"{name}.csv", rec, scale)
        assert main(["identify", str(tmp_path / f"{name}.csv"), *opts, "--method", "oe",
                     "--order", "1", "--add", "cubic_stiffness",
                     "-o", str(tmp_path / f"{name}.yaml")]) == 0
        capsys.readouterr()
        assert main(["compare", str(tmp_path / f"{name}.yaml"), str(tmp_path / f"{name}.csv"),
                     *opts, "--range", "2000:", "--json"]) == 0
        fits.append(json.loads(capsys.readouterr().out)["fit_percent"])
    assert fits[0] >= 90.0 and abs(fits[0] - fits[1]) < 0.1, fits


@pytest.mark.parametrize("bad", ["0", "two", "-1"])
def test_order_must_be_auto_or_positive(tmp_path, capsys, bad):
    opts = _csv(tmp_path / "d.csv", B.duffing(seed=0, n=1500))
    with pytest.raises(SystemExit) as e:
        main(["diagnose", str(tmp_path / "d.csv"), *opts, "--order", bad])
    assert e.value.code == 2 and "--order" in capsys.readouterr().err
