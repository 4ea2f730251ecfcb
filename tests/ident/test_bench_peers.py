"""bench/peers.py: the peers' held-out protocol (estimation data only, free run of the
validation part) and the table it prints."""

import pytest

from bench import peers
from tests.gen import linear


@pytest.fixture(scope="module")
def thermal():
    g = linear.thermal(delay=2, n=900, seed=3)
    return g.u, g.y, slice(0, 600), slice(600, 900)


def test_linear_peers_do_not_read_the_validation_outputs(thermal):
    u, y, est, val = thermal
    a = peers._linear_peer(peers._arx, u, y, est, val)
    assert a["status"] == "ok" and a["fit_percent"] > 90
    y2 = y.copy()
    y2[val] += 1.0   # an offset only the validation outputs carry: the fit must fall
    b = peers._linear_peer(peers._arx, u, y2, est, val)
    assert b["order"] == a["order"] and b["fit_percent"] < a["fit_percent"] - 5
    # validation before the estimation part: simulated from rest
    c = peers._linear_peer(peers._arx, u, y, slice(300, 900), slice(0, 300))
    assert c["status"] == "ok"


def test_narx_peer(thermal):
    pytest.importorskip("sysidentpy")
    u, y, est, val = thermal
    r = peers._narx(u, y, est, val)
    assert r["status"] == "ok" and r["fit_percent"] > 85 and r["settings"][0].startswith("degree")


def test_markdown_table():
    row = {"n": 10, "inputs": 1, "outputs": 1,
           "rigd": {"fit_percent": 90.0, "seconds": 3.0, "effect": "delay",
                    "fit_percent_with_effect": 95.0},
           "lti": {"fit_percent": 91.0, "seconds": 2.0, "cpu_s": 1.6, "family": "lti",
                   "states": 2, "delays": [1]},
           "arx": {"fit_percent": 91.5, "seconds": 1.0, "order": 3},
           "subspace": {"fit_percent": None, "status": "diverged", "seconds": 1.0},
           "narx": {"status": "failed: ValueError: x", "seconds": 0.5}}
    md = peers.markdown({"r": row}).splitlines()
    assert md[2] == ("| r (10, 1×1) | 90.00 (3 s) | 95.00 (delay) | 91.00 (2 s CPU) lti 2 st., "
                     "delays [1] | 91.50 (1 s) n=3 | diverged n=– | failed | -1.50 |")
    # diagnose's base shown when it is another model's (the mechanical base); no margin
    # without a reference figure
    row["rigd"]["diagnose_base"] = 71.1
    row["arx"] = {"fit_percent": None, "status": "diverged", "seconds": 1.0}
    md = peers.markdown({"r": row}).splitlines()
    assert "90.00 (3 s); diagnosed on another base: 71.10 |" in md[2]
    assert md[2].endswith("| failed | – |")
