"""Prefilters (Sec. 4.4) and refusal of bad or inconsistent inputs."""

import numpy as np
import pytest
from ident_helpers import rotor_record

from rigd.data.record import Record
from rigd.errors import InputError
from rigd.ident.iddata import from_record
from rigd.ident.prefilter import PrefilterOptions, apply_prefilters
from rigd.ident.workflow import identify_record

NOISE = 0.02


def test_runout_filter_removes_synchronous_disturbance_to_noise_level():
    clean = rotor_record(n=12000, seed=7, noise=NOISE, omega_rpm=3000)
    dirty = rotor_record(n=12000, seed=7, noise=NOISE, omega_rpm=3000, runout=2.0)
    runout = rotor_record(n=12000, seed=8, noise=NOISE, omega_rpm=3000, runout=2.0,
                          excite=False, kind="runout")
    opt = PrefilterOptions(offsets=False, median=False)
    filt, rep = apply_prefilters(dirty, ["u_x", "u_y"], ["e_x", "e_y"], opt, runout)
    assert rep["runout"] and rep["runout"]["rms_removed"]["e_x"] > 1.0
    phi = dirty.col("phi")
    noise_sd = NOISE * clean.col("e_x").std()
    for c in ("e_x", "e_y"):
        before = dirty.col(c) - clean.col(c)
        after = filt.col(c) - clean.col(c)
        assert before.std() > 1.0                       # disturbance was large
        assert after.std() < 0.5 * noise_sd             # left-over below the noise level
        # no synchronous component left at 1x and 2x
        for k in (1, 2):
            amp = 2 * abs(np.mean(filt.col(c) * np.exp(-1j * k * phi)) -
                          np.mean(clean.col(c) * np.exp(-1j * k * phi)))
            assert amp < 0.5 * noise_sd


def test_offsets_and_median_reported_and_applied():
    rec = rotor_record(n=4000, seed=2)
    shifted = rec.with_columns(e_x=rec.col("e_x") + 10.0, u_x=rec.col("u_x") - 3.0)
    filt, rep = apply_prefilters(shifted, ["u_x", "u_y"], ["e_x", "e_y"])
    assert rep["offsets"]["samples"] == 1000  # a quarter of a short record, else 2000
    # (median 3 runs first, so compare loosely with the raw mean)
    assert abs(rep["offsets"]["values"]["e_x"] - 10.0 - rec.col("e_x")[:1000].mean()) < 0.01
    assert abs(rep["offsets"]["values"]["u_x"] + 3.0 - rec.col("u_x")[:1000].mean()) < 1e-9
    assert abs(filt.col("e_x")[:1000].mean()) < 1e-9
    assert rep["median"]["size"] == 3
    spike = shifted.with_columns(e_y=np.where(np.arange(4000) == 2000, 1e3, shifted.col("e_y")))
    f2, _ = apply_prefilters(spike, ["u_x", "u_y"], ["e_x", "e_y"])
    assert np.abs(f2.col("e_y")).max() < 100   # single-sample spike removed by median 3
    f3, rep3 = apply_prefilters(spike, ["u_x", "u_y"], ["e_x", "e_y"],
                                PrefilterOptions(median=False, offsets=False))
    assert rep3["median"] is False and rep3["offsets"] is False
    assert f3.col("e_y")[2000] == 1e3


def test_runout_record_without_phi_refused():
    rec = rotor_record(n=3000, seed=1, omega_rpm=3000)
    ro = rotor_record(n=3000, seed=2, omega_rpm=3000, excite=False)
    ro = Record({k: v for k, v in ro.columns.items() if k != "phi"}, ro.fs, ro.meta, "ro.csv")
    with pytest.raises(InputError, match="phi") as ei:
        identify_record(rec, "bearing", runout=ro)
    assert "ro.csv" in str(ei.value)


@pytest.mark.parametrize("field,value", [("omega_rpm", 1000.0), ("p_inj_bar", 6.0)])
def test_mismatched_operating_points_refused(field, value):
    rec = rotor_record(n=3000, seed=1, omega_rpm=3000)
    ro = rotor_record(n=3000, seed=2, omega_rpm=3000, excite=False)
    ro.meta[field] = value
    with pytest.raises(InputError, match="same operating point"):
        identify_record(rec, "bearing", runout=ro)


def test_too_short_record_refused():
    rec = rotor_record(n=300, seed=1)
    with pytest.raises(InputError, match="too short"):
        identify_record(rec, "bearing")


def test_missing_columns_for_asked_model_refused():
    rec = rotor_record(n=3000, seed=1)
    no_r = Record({k: v for k, v in rec.columns.items() if k not in ("r_x", "r_y")}, rec.fs,
                  rec.meta, "nor.csv")
    with pytest.raises(InputError, match="r_x, r_y"):
        identify_record(no_r, "actuator")
    with pytest.raises(InputError, match="r_x"):
        identify_record(no_r, "both")
    with pytest.raises(InputError, match="inputs"):
        from_record(no_r, "generic")


def test_non_finite_values_refused():
    rec = rotor_record(n=3000, seed=1)
    bad = rec.with_columns(e_x=np.where(np.arange(3000) == 5, np.nan, rec.col("e_x")))
    with pytest.raises(InputError, match="NaN in column 'e_x' at sample 5, used by the "
                                         "bearing model"):
        from_record(bad, "bearing")
