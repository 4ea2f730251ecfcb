"""tests/sharedruns.py: an output shared by the processes of a test run is made once, a
failed attempt is made again by the next process that asks, and a second process waits for
the one making it instead of making it too."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import pytest
from sharedruns import ENV, shared_folder, shared_value
from testpaths import ROOT


def test_made_once_and_again_after_a_failure(tmp_path, tmp_path_factory, monkeypatch):
    monkeypatch.setenv(ENV, str(tmp_path))
    calls = []

    def make(out):
        calls.append(out)
        out.mkdir()
        (out / "half").write_text("x")
        if len(calls) == 1:
            raise RuntimeError("first attempt fails")
        (out / "whole").write_text("y")

    with pytest.raises(RuntimeError):
        shared_folder("thing", make, tmp_path_factory)
    out = shared_folder("thing", make, tmp_path_factory)
    assert out == tmp_path / "thing" and (out / "whole").read_text() == "y"
    assert shared_folder("thing", make, tmp_path_factory) == out
    assert len(calls) == 2


def test_a_second_process_waits_for_the_first(tmp_path, tmp_path_factory, monkeypatch):
    """A child process holds the lock while it makes the folder slowly; this process asks
    meanwhile, gets the child's folder and never calls its own ``make``."""
    monkeypatch.setenv(ENV, str(tmp_path))
    started = tmp_path / "started"
    child = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""\
        import sys, time
        from pathlib import Path
        sys.path.insert(0, {str(ROOT / "tests")!r})
        from sharedruns import shared_folder

        def make(out):
            Path({str(started)!r}).touch()
            time.sleep(1.0)
            out.mkdir()
            (out / "by").write_text("child")

        shared_folder("thing", make, None)
        """)], env={**os.environ, ENV: str(tmp_path)})
    try:
        for _ in range(6000):
            if started.exists() or child.poll() is not None:
                break
            time.sleep(0.01)
        assert started.exists(), "the child never started making the folder"

        def make(out):
            raise AssertionError("made twice")

        out = shared_folder("thing", make, tmp_path_factory)
        assert (out / "by").read_text() == "child"
    finally:
        assert child.wait(timeout=120) == 0


def test_shared_value_made_once_read_back_as_a_copy(tmp_path, tmp_path_factory, monkeypatch):
    monkeypatch.setenv(ENV, str(tmp_path))
    calls = []

    def make():
        calls.append(1)
        return {"fit": [1.0, 2.0]}

    a = shared_value("value", make, tmp_path_factory)
    a["fit"].append(3.0)                       # a test changing its copy changes no other
    assert shared_value("value", make, tmp_path_factory) == {"fit": [1.0, 2.0]}
    assert len(calls) == 1
