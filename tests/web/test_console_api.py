"""What the console page relies on from the server: ``POST /api/op`` refuses what is not two
finite numbers (an empty form field never becomes 0 rpm) before anything reaches the daemon,
and ``GET /api/ping`` gives the daemon's identity (pid) that the live plots carry."""

import os

import pytest
from webkit import auth


@pytest.mark.parametrize("body, field", [
    ({"p_inj_bar": 4.0}, "omega_rpm"),
    ({"omega_rpm": "", "p_inj_bar": 4.0}, "omega_rpm"),
    ({"omega_rpm": "2000", "p_inj_bar": 4.0}, "omega_rpm"),
    ({"omega_rpm": True, "p_inj_bar": 4.0}, "omega_rpm"),
    ({"omega_rpm": 2000, "p_inj_bar": None}, "p_inj_bar"),
    ({"omega_rpm": 2000, "p_inj_bar": [5]}, "p_inj_bar"),
])
def test_op_needs_two_numbers_and_nothing_reaches_the_daemon(site, body, field):
    client, loop, _, _ = site
    r = client.post("/api/op", json=body, headers=auth())
    assert r.status_code == 400
    err = r.json()["error"]
    assert err.startswith(f"op: {field}: a finite number is required") and "\n" not in err
    assert loop.calls == []


def test_op_with_numbers_is_applied_and_echoed(site):
    client, loop, _, _ = site
    r = client.post("/api/op", json={"omega_rpm": 2000, "p_inj_bar": 5.5}, headers=auth())
    assert r.status_code == 200, r.text
    assert r.json() == {"omega_rpm": 2000.0, "p_inj_bar": 5.5}
    assert loop.calls == [("set_operating_point", 2000.0, 5.5)]


def test_ping_names_the_daemon(site):
    client, _, _, _ = site
    r = client.get("/api/ping", headers=auth())
    assert r.status_code == 200 and r.json()["pid"] == os.getpid()
