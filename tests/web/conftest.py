"""Fixtures of the web console's tests: the app on a real control socket whose loop is the
service tests' loop double (every command that reaches the daemon is in ``loop.calls``)."""

import os
import sys

import pytest
from starlette.testclient import TestClient
from testpaths import ROOT

sys.path.append(str(ROOT / "tests" / "service"))  # the loop double (fakeloop.py)

from fakeloop import FakeLoop  # noqa: E402
from webkit import READ_TOKEN, TOKEN, FakeExperiments, auth  # noqa: E402

from rigd.service.protocol import Dispatcher  # noqa: E402
from rigd.service.server import ControlServer  # noqa: E402
from rigd.web.app import Settings, build_app  # noqa: E402


@pytest.fixture
def site(tmp_path):
    """``(client, loop, experiments, settings)``: the app talking to a real socket server; the
    client sends the control token on every request (``client.headers``)."""
    loop, exps = FakeLoop(), FakeExperiments()
    (tmp_path / "runs").mkdir()
    (tmp_path / "config").mkdir()
    disp = Dispatcher(loop, experiments=exps, info=lambda: {"pid": os.getpid()})
    with ControlServer(tmp_path / "d.sock", disp.handle_line) as srv:
        settings = Settings(socket=str(srv.path), runs_dir=(tmp_path / "runs").resolve(),
                            config_dir=(tmp_path / "config").resolve(), token=TOKEN,
                            read_token=READ_TOKEN)
        with TestClient(build_app(settings), headers=auth()) as client:
            yield client, loop, exps, settings
