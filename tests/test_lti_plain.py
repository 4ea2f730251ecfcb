"""The leaf helpers: exact discretisation (rigd.lti) and plain values for JSON/YAML (rigd.plain)."""

import json
import math

import numpy as np
import pytest
import yaml
from scipy import signal

from rigd import lti
from rigd.plain import plain

# a lightly damped 2-DOF mechanical system (x = [p, ṗ]), two inputs
A = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0],
              [-(2 * np.pi * 110) ** 2, 3e4, -40.0, 2.0],
              [1e4, -(2 * np.pi * 150) ** 2, 1.5, -55.0]])
B = np.array([[0.0, 0.0], [0.0, 0.0], [3e4, 0.0], [2e3, 2.5e4]])
C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
FS = 5000.0


def _run(Ad, Bs, u):
    x = np.zeros(A.shape[0])
    out = []
    for k in range(len(u) - 1):
        out.append(C @ x)
        x = Ad @ x + sum(Bj @ uj for Bj, uj in zip(Bs, (u[k], u[k + 1])))
    return np.array(out)


def test_zoh_and_foh_match_continuous_simulation():
    """ZOH = scipy's lsim with the input held; FOH = lsim with the input linear between samples
    (its default interpolation)."""
    rng = np.random.default_rng(0)
    n = 400
    t = np.arange(n) / FS
    u = rng.standard_normal((n, 2))
    sys_c = signal.StateSpace(A, B, C, np.zeros((2, 2)))
    Ad, Bd = lti.zoh(A, B, 1 / FS)
    y_zoh = _run(Ad, [Bd, np.zeros_like(Bd)], u)
    _, y_held, _ = signal.lsim(sys_c, u, t, interp=False)
    assert np.allclose(y_zoh, y_held[:-1], rtol=1e-7, atol=1e-9 * np.abs(y_held).max())
    Af, B0, B1 = lti.foh(A, B, 1 / FS)
    assert np.allclose(Af, Ad)
    y_foh = _run(Af, [B0, B1], u)
    _, y_lin, _ = signal.lsim(sys_c, u, t, interp=True)
    assert np.allclose(y_foh, y_lin[:-1], rtol=1e-7, atol=1e-9 * np.abs(y_lin).max())
    # the held and the linear input give clearly different answers (the test can fail)
    assert np.abs(y_zoh - y_foh).max() > 1e-3 * np.abs(y_foh).max()


def test_a_faster_expm_gives_the_same_matrices_and_nonfinite_gives_nan():
    from rigd.ident.sim_kernels import expm_kernel

    for got, ref in zip(lti.foh(A, B, 1 / FS, expm=expm_kernel), lti.foh(A, B, 1 / FS)):
        assert np.allclose(got, ref, rtol=1e-10, atol=1e-14)
        assert got.flags.c_contiguous
    Ad, Bd = lti.zoh(A * np.nan, B, 1 / FS)
    assert np.isnan(Ad).all() and np.isnan(Bd).all()


def test_plain_one_nan_policy_for_json_and_yaml():
    value = {1: np.array([1.5, np.nan]), "t": (np.float32(2.0), np.int64(3)),
             "inf": -math.inf, "b": b"caf\xc3\xa9", "z": 1 + 2j, "ok": True, "none": None}
    got = plain(value)
    assert got == {"1": [1.5, None], "t": [2.0, 3], "inf": None, "b": "café", "z": "(1+2j)",
                   "ok": True, "none": None}
    assert type(got["t"][1]) is int and type(got["t"][0]) is float
    text = json.dumps(got, allow_nan=False)     # strict JSON: would raise on a NaN left
    assert json.loads(text) == got
    assert yaml.safe_load(yaml.safe_dump(got)) == got
    with pytest.raises(ValueError):
        json.dumps(value[1].tolist(), allow_nan=False)
