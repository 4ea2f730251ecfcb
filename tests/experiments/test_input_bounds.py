"""Bad input refused in one clear line before anything runs: experiment sizes, run-folder
names, ``op`` values, ``--record`` names (and no writer ever replaces a file)."""

import datetime as dt
import json

import pytest

from rigd.cli.run import record_path
from rigd.errors import InputError
from rigd.experiments.manifest import new_run_dir
from rigd.experiments.runner import run_experiment
from rigd.experiments.schemas import spec_from_dict
from rigd.fileio import rename_new
from rigd.recording.h5sink import H5Sink
from rigd.service.protocol import RequestError, parse_request


class _NoLoop:
    """Validation happens before a loop is touched: a loop that only says its rate."""

    fs = 5000.0

    def status(self):
        return {"fault": {}, "controller": {"loaded": False, "enabled": False}}

    def run_segment(self, *a, **k):  # pragma: no cover - must not be reached
        raise AssertionError("ran a segment")


def test_a_million_revolutions_at_1_rpm_is_refused_naming_the_key_and_limit(tmp_path):
    spec = {"kind": "runout", "revolutions": 1_000_000,
            "operating_point": {"omega_rpm": 1.0, "p_inj_bar": 4.0}}
    with pytest.raises(InputError) as e:
        run_experiment(spec, _NoLoop(), tmp_path / "run")
    text = str(e.value)
    assert "revolutions" in text and "4200 s per record" in text and "6e+07 s" in text, text
    assert not (tmp_path / "run").exists()          # nothing created
    sweep = {"kind": "sweep", "grid": {"omega_rpm": [1.0, 3000.0], "p_inj_bar": [4.0]},
             "at_each": {"kind": "runout", "revolutions": 100_000}}
    with pytest.raises(InputError, match="revolutions: 100000 revolutions at 1 rpm"):
        run_experiment(sweep, _NoLoop(), tmp_path / "run2")


def test_a_multisine_longer_than_the_limit_is_refused_at_validation():
    with pytest.raises(InputError, match="over the limit of 4200 s per record"):
        spec_from_dict({"kind": "multisine", "amplitude_v": 0.1, "f_min_hz": 1.0,
                        "f_max_hz": 100.0, "period_s": 600.0, "periods": 10000})


@pytest.mark.parametrize("name, what", [("run\nfake", "U+000A"), ("run\u202efdp.h5", "U+202E"),
                                        ("a\u200bb", "U+200B"), ("x\x1b[31m", "U+001B")])
def test_run_folder_names_with_control_or_bidi_characters_are_refused(tmp_path, name, what):
    with pytest.raises(InputError) as e:
        new_run_dir(tmp_path / name, "x")
    assert what in str(e.value) and "refused" in str(e.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value, says", [
    (float("nan"), "omega_rpm: must be a finite number (got nan)"),
    (1e9, "omega_rpm: must be <= 100000 (got 1e+09)"),
    (-1.0, "omega_rpm: must be >= 0 (got -1)"),
    ("fast", "omega_rpm: must be a number (got str 'fast')"),
])
def test_op_values_come_back_in_one_plain_line(value, says):
    line = json.dumps({"id": 1, "cmd": "operating_point.set", "omega_rpm": value,
                       "p_inj_bar": 4.0})
    with pytest.raises(RequestError) as e:
        parse_request(line)
    assert str(e.value) == f"operating_point.set: {says}"
    with pytest.raises(RequestError, match="p_inj_bar: missing: this argument is required"):
        parse_request(json.dumps({"id": 1, "cmd": "operating_point.set", "omega_rpm": 1.0}))


def test_record_names_never_name_an_existing_file(tmp_path):
    x = tmp_path / "X.h5"
    x.write_bytes(b"keep")
    with pytest.raises(InputError, match="exists: a record is never overwritten"):
        record_path(str(x))
    now = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.timezone.utc)
    assert record_path(str(tmp_path / "crash-{start}.h5"), now).name == \
        "crash-20260102T030405Z.h5"
    (tmp_path / "crash-20260102T030405Z.h5").write_bytes(b"")
    assert record_path(str(tmp_path / "crash-{start}.h5"), now).name == \
        "crash-20260102T030405Z-2.h5"
    assert record_path(str(tmp_path) + "/", now) == tmp_path / "rigd-20260102T030405Z.h5"
    with pytest.raises(InputError, match="only field of a pattern is"):
        record_path(str(tmp_path / "r-{host}.h5"))
    assert x.read_bytes() == b"keep"


def test_no_writer_replaces_a_file(tmp_path):
    x = tmp_path / "X.h5"
    x.write_bytes(b"keep")
    with pytest.raises(FileExistsError):
        H5Sink(x, fs=5000.0)
    y = tmp_path / "Y.h5"
    y.write_bytes(b"other")
    with pytest.raises(FileExistsError):
        rename_new(y, x)
    assert x.read_bytes() == b"keep" and y.read_bytes() == b"other"
    rename_new(y, tmp_path / "Z.h5")
    assert not y.exists() and (tmp_path / "Z.h5").read_bytes() == b"other"
