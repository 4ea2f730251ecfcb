"""Operating range: a sweep run directory -> parameter table and G_bear(Ω, P_I)."""

import json

import numpy as np
from ident_helpers import rotor_record

from rigd.cli import main
from rigd.data.csvio import write_csv
from rigd.ident.oprange import ReassembledBearing


def _run_dir(tmp_path):
    files = []
    for w in (0.0, 3000.0):
        for p in (4.0, 6.0):
            name = f"w{w:g}_p{p:g}_prbs.csv"
            rec = rotor_record(n=6000, seed=int(w + 10 * p), omega_rpm=w, p_inj_bar=p,
                               kscale=p / 4.0)
            write_csv(tmp_path / name, rec)
            files.append({"path": name, "kind": "prbs", "omega_rpm": w, "p_inj_bar": p})
    files.append({"path": "gone.csv", "kind": "prbs", "omega_rpm": 0, "p_inj_bar": 5.0})
    (tmp_path / "manifest.json").write_text(json.dumps({"rigd_manifest": 1, "files": files}))
    return tmp_path


def test_sweep_identifies_every_point_and_interpolates(tmp_path, capsys):
    run = _run_dir(tmp_path / "run")
    out = tmp_path / "gbear.yaml"
    assert main(["identify", str(run), "-o", str(out), "--json", "--jobs", "2"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert len(js["fit_percent"]) == 4 and min(js["fit_percent"].values()) > 95
    assert any("gone.csv" in n for n in js["notes"])
    g = ReassembledBearing.load(out)
    f4 = g.modes(0, 4.0)[0]["f_n_hz"]
    f6 = g.modes(0, 6.0)[0]["f_n_hz"]
    assert abs(f6 / f4 - np.sqrt(1.5)) < 0.01            # stiffness scales with P_I here
    f5 = g.modes(1500, 5.0)[0]["f_n_hz"]
    assert f4 < f5 < f6                                   # interpolated in between
    ss = g.at(1500, 5.0)
    assert ss.ninputs == 2 and ss.noutputs == 2 and ss.nstates == 4
    # outside the grid: clipped to its edge
    np.testing.assert_allclose(g.theta(9000, 6.0), g.theta(3000, 6.0))
    assert (out.parent / "gbear_report" / "modes.png").exists()


def test_run_dir_without_manifest_refused(tmp_path, capsys):
    assert main(["identify", str(tmp_path)]) == 2
    assert "manifest" in capsys.readouterr().err
