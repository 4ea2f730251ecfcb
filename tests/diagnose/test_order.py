"""Base model of the right order (rigd.ident.greybox.order, rigd.ident.lti.subspace): subspace
estimate, output-error refinement, number of modes by validation fit; model files and compare."""

import json

import benchmarks as B  # tests/diagnose/benchmarks.py
import numpy as np
import pytest
from scipy import signal

from rigd.cli import main
from rigd.ident.lti.subspace import continuous_modes, dynamics_matrices, n4sid


def test_n4sid_recovers_two_modes_of_a_known_system():
    fs = 1000.0
    modes = [(31.0, 0.02), (140.0, 0.03)]
    num, den = np.array([0.0]), np.array([1.0])
    for f, z in modes:
        w = 2 * np.pi * f
        num = np.polyadd(np.polymul(num, [1, 2 * z * w, w * w]), np.polymul(den, [w * w]))
        den = np.polymul(den, [1, 2 * z * w, w * w])
    rng = np.random.default_rng(0)
    u = rng.standard_normal(6000)
    _, y = signal.dlsim(signal.cont2discrete((num, den), 1 / fs, "zoh"), u)
    y = y[:, 0] + 0.01 * np.std(y) * rng.standard_normal(len(u))
    A = n4sid(u, y, 4, horizon=20).model.A
    got = continuous_modes(A, fs)
    assert len(got) == 2
    for (f, z), (ft, zt) in zip(got, modes):
        assert abs(f - ft) < 0.01 * ft and abs(z - zt) < 0.3 * zt, got


def test_dynamics_matrices_are_n4sids_a_from_one_decomposition_per_horizon():
    """candidate_mode's subspace A's (one decomposition per horizon, no B/D/K/x0 steps) are
    n4sid's own, bit for bit; an order the horizon cannot carry or a record too short for
    the horizon gives None, as n4sid raises."""
    rng = np.random.default_rng(3)
    u = rng.standard_normal((900, 2))
    y = signal.lfilter([0.0, 0.4, 0.2], [1.0, -1.5, 0.8], u[:, 0])[:, None] + \
        0.3 * np.roll(u[:, 1:], 2, axis=0) + 0.01 * rng.standard_normal((900, 1))
    tries = [(order, hz) for order in (2, 4, 6) for hz in (None, 4 * order + 10)]
    got = dynamics_matrices(u, y, tries)
    for (order, hz), A in zip(tries, got):
        np.testing.assert_array_equal(A, n4sid(u, y, order, horizon=hz).model.A)
    # horizon 3 with one output carries at most 2 states; 80 block rows need more samples
    assert dynamics_matrices(u, y, [(3, 3), (2, 80)]) == [None, None]
    for order, hz in ((3, 3), (2, 80)):
        with pytest.raises(ValueError):
            n4sid(u, y, order, horizon=hz)


def _csv(path, rec):
    u, y = rec.inputs[0], rec.outputs[0]
    np.savetxt(path, np.column_stack([rec.col(u), rec.col(y)]), delimiter=",",
               header=f"{u},{y}", comments="")
    return ["--fs", str(rec.fs), "--inputs", u, "--outputs", y]


def test_identify_order_auto_model_file_and_compare(tmp_path, capsys):
    rec = B.three_mode(seed=5)
    opts = _csv(tmp_path / "d.csv", rec)
    assert main(["identify", str(tmp_path / "d.csv"), *opts, "--method", "oe", "--json",
                 "-o", str(tmp_path / "m.yaml")]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["fit_percent"] >= 95.0
    assert js["fit_percent_per_output"]["generic"]["order"]["modes"] == 3
    # the model file keeps the modes (and their initial states, re-estimated by compare)
    assert main(["compare", str(tmp_path / "m.yaml"), str(tmp_path / "d.csv"), *opts,
                 "--range", "5000:", "--json"]) == 0
    cmp = json.loads(capsys.readouterr().out)
    assert cmp["fit_percent"] >= 95.0
    # a fixed order below one mode per output is refused in one line
    with pytest.raises(SystemExit) as e:
        main(["identify", str(tmp_path / "d.csv"), *opts, "--order", "0"])
    assert e.value.code == 2 and "--order" in capsys.readouterr().err
    # --order N is a number of states (2 per mode), fitted exactly
    assert main(["identify", str(tmp_path / "d.csv"), *opts, "--order", "2", "--method", "oe",
                 "--json"]) == 0
    js1 = json.loads(capsys.readouterr().out)
    o1 = js1["fit_percent_per_output"]["generic"]["order"]
    assert o1["states"] == 2 and o1["modes"] == 1 and o1["asked"] == 2
    assert js1["fit_percent"] < js["fit_percent"] - 10


def test_order_n_is_states_exact_or_refused_from_the_cli(tmp_path, capsys):
    """--order N counts states on every base; what cannot be fitted exactly is refused in one
    line naming --order (exit 2), nothing written; what is fitted says what was asked."""
    rec = B.duffing(seed=0, n=3000)
    opts = _csv(tmp_path / "d.csv", rec)
    model = tmp_path / "m.yaml"
    refused = [["--order", "31"],                                 # more than the LTI family
               ["--order", "3", "--add", "cubic_stiffness"],      # the mechanical base: odd
               ["--order", "1", "--add", "cubic_stiffness"]]      # below one mode per output
    for extra in refused:
        assert main(["identify", str(tmp_path / "d.csv"), *opts, "--method", "oe", *extra,
                     "-o", str(model)]) == 2, extra
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--order" in err[0] and "refused" in err[0], err
        assert not model.exists()
    # on the mechanical base (asked for by an effect on a mechanical state): 2 states = 1 mode
    assert main(["identify", str(tmp_path / "d.csv"), *opts, "--method", "oe", "--order", "2",
                 "--add", "cubic_stiffness", "--json"]) == 0
    o = json.loads(capsys.readouterr().out)["fit_percent_per_output"]["generic"]["order"]
    assert (o["family"], o["states"], o["modes"], o["asked"]) == ("mechanical", 2, 1, 2), o
    # the human output prints the states, the modes and what was asked
    assert main(["identify", str(tmp_path / "d.csv"), *opts, "--method", "oe",
                 "--order", "3"]) == 0
    out = capsys.readouterr().out
    assert "base model: lti, 3 state(s)" in out and "--order 3" in out, out
