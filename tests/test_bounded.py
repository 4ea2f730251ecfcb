"""Bounded reading (rigd.bounded): regular files only, the size checked before reading, run
folders confined to the runs folder — each refusal one line naming the file and the problem."""

import os
import threading

import pytest

from rigd import bounded
from rigd.configio import read_yaml
from rigd.controller import load_controller, save_controller
from rigd.errors import InputError


def _refused(path, limit=1 << 20, what="controller file"):
    with pytest.raises(InputError) as ei:
        bounded.read_regular(path, limit, what)
    msg = str(ei.value)
    assert "\n" not in msg and str(path) in msg
    return msg


def test_devices_directories_and_fifos_are_refused_without_reading(tmp_path):
    assert "a character device" in _refused("/dev/zero")
    assert "a directory" in _refused(tmp_path)
    fifo = tmp_path / "k.fifo"
    os.mkfifo(fifo)
    # no writer ever comes: a blocking open would hang here; the refusal comes at once
    done = threading.Event()
    msgs = []
    t = threading.Thread(target=lambda: (msgs.append(_refused(fifo)), done.set()), daemon=True)
    t.start()
    assert done.wait(60), "reading a FIFO blocked"
    assert "FIFO" in msgs[0] and "regular file" in msgs[0]


def test_a_large_sparse_file_is_refused_by_its_size(tmp_path):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as f:
        f.truncate(500 << 20)              # 500 MB, no block written
    msg = _refused(big, bounded.MAX_CONTROLLER_BYTES)
    assert "500 MiB" in msg and "limit of 4 MiB" in msg
    # the loaders go through it: a controller, any YAML
    with pytest.raises(InputError, match="larger than the limit"):
        load_controller(big, expected_fs_hz=5000.0)
    with pytest.raises(InputError, match="a character device"):
        read_yaml("/dev/zero")


def test_a_regular_file_within_the_limit_is_read_and_one_byte_more_is_not(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_bytes(b"a: 1\n" * 100)
    assert bounded.read_regular(p, 500) == b"a: 1\n" * 100
    assert "larger than the limit" in _refused(p, 499)
    p.write_bytes(b"\xff\xfe")
    with pytest.raises(InputError, match="not UTF-8"):
        bounded.read_text(p)
    with pytest.raises(InputError, match="no such file"):
        bounded.read_regular(tmp_path / "missing", 10)


def test_a_symlink_to_a_device_is_refused_as_the_device(tmp_path):
    link = tmp_path / "k.yaml"
    link.symlink_to("/dev/zero")
    assert "a character device" in _refused(link)


def test_a_valid_controller_still_loads(tmp_path):
    k = tmp_path / "k.yaml"
    save_controller(k, [[0.5]], [[0.0, 1.0]], [[1.0], [0.0]], [[0.0, 0.0], [0.0, 0.0]],
                    fs_hz=5000.0)
    assert load_controller(k, expected_fs_hz=5000.0).order == 1


def test_run_folders_are_confined_to_the_runs_folder(tmp_path):
    runs = tmp_path / "runs"
    (runs / "ok").mkdir(parents=True)
    assert bounded.confined(runs / "ok" / "new", runs, "run_dir") == runs / "ok" / "new"
    (runs / "out").symlink_to(tmp_path)                 # a symlink out of the runs folder
    for bad in (tmp_path / "elsewhere", runs / ".." / "x", runs / "out" / "x", runs, "/tmp"):
        with pytest.raises(InputError, match="must be inside the runs folder") as ei:
            bounded.confined(bad, runs, "experiment.start: run_dir")
        assert str(ei.value).startswith("experiment.start: run_dir: ")
