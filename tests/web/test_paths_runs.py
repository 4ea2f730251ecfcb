"""No path outside the runs and config folders is served or named to the daemon; the runs
listing (manifests) and the server-side decimated record view; uploads validated with the
CLI's loader."""

import json
import os
from pathlib import Path

import numpy as np
import pytest
from testpaths import ROOT
from webkit import auth

from rigd.cli import main
from rigd.controller import save_controller
from rigd.data.csvio import write_csv
from rigd.data.record import Record
from rigd.experiments.manifest import Manifest
from rigd.web.paths import PathRefused, resolve_inside
from rigd.web.runs import minmax

SECRET = "top-secret-outside-the-runs-folder"


@pytest.fixture
def tree(site, tmp_path):
    client, loop, exps, settings = site
    (tmp_path / "secret.txt").write_text(SECRET)
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "k.yaml").write_text(SECRET)
    run = settings.runs_dir / "run1"
    (run / "report").mkdir(parents=True)
    (run / "report" / "index.html").write_text("<html>report page</html>")
    os.symlink(tmp_path / "secret.txt", run / "link.txt")
    os.symlink(tmp_path / "outside", settings.runs_dir / "escape")
    os.symlink(tmp_path / "outside", settings.config_dir / "escape")
    os.symlink(run / "report" / "index.html", run / "inside.html")
    return client, loop, exps, settings


@pytest.mark.parametrize("url", [
    "/runs/../secret.txt", "/runs/%2e%2e/secret.txt", "/runs/%2E%2E%2Fsecret.txt",
    "/runs/run1/..%2f..%2fsecret.txt", "/runs/run1/link.txt", "/runs/escape/k.yaml",
    "/runs//etc/passwd", "/runs/%2fetc%2fpasswd", "/runs/run1/report/..%5c..%5csecret.txt",
    "/api/runs/%2e%2e/secret.txt", "/api/runs/escape/k.yaml", "/runs/run1/%00x",
])
def test_no_file_outside_the_runs_folder_is_served(tree, url):
    client = tree[0]
    r = client.get(url)
    assert r.status_code in (400, 404), (url, r.status_code)
    assert SECRET not in r.text


def test_files_inside_are_served_symlinks_inside_too(tree):
    client = tree[0]
    assert client.get("/runs/run1/report/index.html").text == "<html>report page</html>"
    assert "report page" in client.get("/runs/run1/inside.html").text


@pytest.mark.parametrize("path", [
    "config/../secret.txt", "config/escape/k.yaml", "runs/escape/k.yaml", "/etc/passwd",
    "etc/passwd", "config//etc/passwd", "config/%2e%2e/secret.txt", "runs/../../secret.txt",
    "config/..\\secret.txt", "config/",
])
@pytest.mark.parametrize("cmd", ["load", "start"])
def test_no_path_outside_reaches_the_daemon(tree, cmd, path):
    client, loop, exps, _ = tree
    r = client.post(f"/api/{cmd}", json={"path": path}, headers=auth())
    assert r.status_code == 400, (cmd, path, r.text)
    assert "\n" not in r.json()["error"] and SECRET not in r.text
    assert loop.calls == [] and exps.started == []


def test_resolve_inside_rules(tmp_path):
    (tmp_path / "a").mkdir()
    assert resolve_inside(tmp_path, "a/b.yaml") == (tmp_path / "a" / "b.yaml").resolve()
    for bad in ["", "..", "a/../..", "a/./b", "/abs", "a\\b", "a//b", "x\x00y"]:
        with pytest.raises(PathRefused):
            resolve_inside(tmp_path, bad)


def test_load_from_config_reaches_the_daemon_with_the_absolute_path(site):
    client, loop, _, settings = site
    save_controller(settings.config_dir / "k.yaml", [[0.5]], [[0.0, 0.0]], [[0.0], [0.0]],
                    [[0.0, 0.0], [0.0, 0.0]], fs_hz=5000.0)
    r = client.post("/api/load", json={"path": "config/k.yaml"}, headers=auth())
    assert r.status_code == 200
    assert loop.calls == [("load_controller", str(settings.config_dir / "k.yaml"))]
    r = client.post("/api/load", json={"path": "config/missing.yaml"}, headers=auth())
    assert r.status_code == 400 and "missing.yaml" in r.json()["error"]


BAD_EXPERIMENT = """kind: prbs
name: bad
operating_point: {omega_rpm: 0, p_inj_bar: 4.0}
amplitude_v: 1.0
duration_s: -4.0
"""


def test_invalid_experiment_upload_is_the_clis_one_line_and_nothing_starts(site, tmp_path,
                                                                          capsys):
    client, loop, exps, settings = site
    r = client.post("/api/start", json={"upload": {"name": "bad.yaml", "text": BAD_EXPERIMENT}},
                    headers=auth())
    assert r.status_code == 400
    err = r.json()["error"]
    # the same message `rigd experiment` prints for the same file (the CLI's loader)
    f = tmp_path / "bad.yaml"
    f.write_text(BAD_EXPERIMENT)
    assert main(["experiment", str(f), "--lockstep"]) == 2
    cli_err = capsys.readouterr().err.strip().split(": ", 1)[1]   # without "rigd experiment: "
    assert err == "start: " + cli_err.replace(str(f), "bad.yaml"), (err, cli_err)
    assert "bad.yaml:5" in err and "duration_s" in err and "\n" not in err
    assert exps.started == [] and loop.calls == []
    assert not (settings.runs_dir / "uploads").exists(), "a refused upload is not kept"


def test_valid_experiment_upload_is_kept_and_started(site):
    client, _, exps, settings = site
    text = (ROOT / "config" / "experiments" / "prbs.yaml").read_text()
    r = client.post("/api/start", json={"upload": {"name": "prbs.yaml", "text": text}},
                    headers=auth())
    assert r.status_code == 200, r.text
    [path] = exps.started
    assert path.startswith(str(settings.runs_dir / "uploads")) and path.endswith("prbs.yaml")
    assert Path(path).read_text() == text
    r = client.post("/api/start", json={"upload": {"name": "../x.yaml", "text": text}},
                    headers=auth())
    assert r.status_code == 200 and exps.started[-1].endswith("-experiment-x.yaml")
    r = client.post("/api/start", json={"upload": {"name": ".hidden", "text": text}},
                    headers=auth())
    assert r.status_code == 400 and len(exps.started) == 2


def test_minmax_keeps_every_peak():
    rng = np.random.default_rng(0)
    x = rng.normal(size=100_003)
    x[77_777] = 50.0
    x[12_345] = -60.0
    idx, lo, hi = minmax(x, 500)
    assert len(idx) == len(lo) == len(hi) == 500 and idx[0] == 0
    assert hi.max() == 50.0 and lo.min() == -60.0
    assert np.all(lo <= hi)
    idx, lo, hi = minmax(x[:7], 500)                     # short: every sample its own bucket
    assert np.array_equal(lo, x[:7]) and np.array_equal(hi, x[:7])


def _record_run(settings, n=50_000):
    run = settings.runs_dir / "20260101T000000Z-prbs"
    run.mkdir()
    t = np.arange(n) / 5000.0
    e_x = np.sin(2 * np.pi * 3 * t)
    e_x[31_000] = 9.0
    cols = {"t": t, "r_x": np.zeros(n), "r_y": np.zeros(n), "u_x": np.zeros(n),
            "u_y": np.zeros(n), "e_x": e_x, "e_y": np.cos(2 * np.pi * 3 * t)}
    write_csv(run / "rec.csv", Record(cols, 5000.0, {"omega_rpm": 0.0, "p_inj_bar": 4.0,
                                                      "kind": "prbs"}))
    man = Manifest(run_dir=run, experiment={"kind": "prbs", "name": "prbs-w0-p4",
                                            "operating_point": {"omega_rpm": 0,
                                                                "p_inj_bar": 4.0}},
                   mode="realtime", fs_hz=5000.0, source="simulated", status="complete",
                   started="2026-01-01T00:00:00+00:00", finished="2026-01-01T00:00:12+00:00")
    man.write()
    return run


def test_runs_listing_from_manifests(site):
    client, _, _, settings = site
    _record_run(settings)
    (settings.runs_dir / "junk").mkdir()
    (settings.runs_dir / "broken").mkdir()
    (settings.runs_dir / "broken" / "manifest.json").write_text("{")
    runs = {r["name"]: r for r in client.get("/api/runs").json()}
    r = runs["20260101T000000Z-prbs"]
    assert (r["kind"], r["source"], r["status"], r["duration_s"]) == ("prbs", "simulated",
                                                                      "complete", 12.0)
    assert r["operating_point"] == {"omega_rpm": 0, "p_inj_bar": 4.0}
    assert r["records"] == ["rec.csv"]
    assert runs["junk"]["error"] == "no manifest.json"
    assert "unreadable manifest" in runs["broken"]["error"]


def test_record_view_is_decimated_server_side_and_zooms(site):
    client, _, _, settings = site
    _record_run(settings)
    r = client.get("/api/runs/20260101T000000Z-prbs/rec.csv?points=400&channels=e_x,e_y")
    assert r.status_code == 200
    v = r.json()
    assert v["n"] == 50_000 and v["decimated"] and len(v["t_s"]) == 400
    assert set(v["channels"]) == {"e_x", "e_y"}
    assert max(v["channels"]["e_x"]["max"]) == 9.0           # the one-sample peak survives
    assert len(json.dumps(v)) < 60_000
    z = client.get("/api/runs/20260101T000000Z-prbs/rec.csv?points=400&t0=6.19&t1=6.21"
                   "&channels=e_x").json()
    assert z["start"] == 30_950 and not z["decimated"] and 9.0 in z["channels"]["e_x"]["max"]
    bad = client.get("/api/runs/20260101T000000Z-prbs/rec.csv?channels=nope")
    assert bad.status_code == 400 and "nope" in bad.json()["error"]
    assert client.get("/api/runs/20260101T000000Z-prbs/none.csv").status_code == 404
