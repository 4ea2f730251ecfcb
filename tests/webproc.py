"""A real daemon (``rigd run``, tests/service/daemon_helpers.py) and a real ``rigd web``
process for the console's process and browser tests (import as ``from webproc import ...``)."""

from __future__ import annotations

import contextlib
import json
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

from testpaths import ROOT

sys.path.append(str(ROOT / "tests" / "service"))

from daemon_helpers import RIGD, Daemon, make_config  # noqa: E402

from rigd.controller import save_controller  # noqa: E402

SHORT_PRBS = """kind: prbs
name: web-short
operating_point: {omega_rpm: 0, p_inj_bar: 4.0}
amplitude_v: 0.5
axes: [x, y]
switch_probability: 0.5
min_hold_s: 0.0002
seed: 3
duration_s: 0.6
lead_in_s: 0.1
controller: false
"""


def write_controller(path: Path) -> Path:
    """A small stable K∞(z) (leaky integrator of -p', 0.01 V/µm), as the daemon tests use."""
    save_controller(path, [[0.99]], [[0.001, 0.0]], [[1.0], [0.0]],
                    [[0.0, 0.0], [0.0, 0.0]], fs_hz=5000.0)
    return path


def start_daemon(tmp: Path, daemon_args: tuple[str, ...] = ()) -> Daemon:
    """``rigd run`` on the simulated rig with a controller loaded (K∞ off), READY waited;
    ``daemon_args`` are more ``rigd run`` options (e.g. ``("--client-idle-s", "3600")``)."""
    ctrl = write_controller(tmp / "k.yaml")
    d = Daemon(tmp, make_config(tmp), "--controller", str(ctrl), *daemon_args)
    try:
        d.wait_notify("READY=1")
    except BaseException:
        d.stop()
        raise
    return d


def config_folder(tmp: Path) -> Path:
    """A config folder as the page offers it: experiments/ and a controller."""
    cfg = tmp / "config"
    (cfg / "experiments").mkdir(parents=True)
    shutil.copy(ROOT / "config" / "experiments" / "prbs.yaml", cfg / "experiments" / "prbs.yaml")
    (cfg / "experiments" / "web-short.yaml").write_text(SHORT_PRBS)
    write_controller(cfg / "controller-k.yaml")
    return cfg


#: the start lines of ``rigd web`` that carry its one-click URLs (the open line comes last)
OPEN, READ_URL = "rigd web: open ", "rigd web: read-only URL"


class WebProcess:
    """``rigd web --listen 127.0.0.1:0`` as a process; ``url``, ``token`` (control),
    ``read_token`` (``--read-token-file``) and the printed ``login_url`` once serving.

    ``args`` replace or add options (``{"--listen": "0.0.0.0:0", "--insecure": None}``);
    ``preexec_fn`` runs in the child before ``rigd web`` starts (e.g. a descriptor limit).
    """

    def __init__(self, tmp: Path, socket: str, runs_dir: Path, config_dir: Path,
                 timeout: float = 300.0, args: dict | None = None, preexec_fn=None,
                 name: str = "web"):
        self.token_file = tmp / f"{name}-token"
        self.read_token_file = tmp / f"{name}-read-token"
        self.lines: list[str] = []
        self._serving = threading.Event()
        opts = {"--listen": "127.0.0.1:0", "--socket": socket, "--runs-dir": str(runs_dir),
                "--config-dir": str(config_dir), "--token-file": str(self.token_file),
                "--read-token-file": str(self.read_token_file),
                "--timeout": "60"}                  # a busy shared test machine
        opts.update(args or {})
        argv = [RIGD, "web"]
        for k, v in opts.items():
            argv += [k] if v is None else [k, v]
        self.proc = subprocess.Popen(
            argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            text=True, cwd=str(tmp), preexec_fn=preexec_fn)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if not self._serving.wait(timeout):
            self.stop()
            raise AssertionError(f"rigd web did not start: {self.lines}")
        line = next(x for x in self.lines if "serving http" in x)
        self.url = line.split("serving ", 1)[1].split()[0].rstrip("/")
        #: the one-click URLs it printed (``.../#token=<control>``, the read-only one or None)
        self.login_url = next(x for x in self.lines if x.startswith(OPEN)).split()[-1]
        self.read_login_url = next((x.split()[-1] for x in self.lines
                                    if x.startswith(READ_URL)), None)
        self.token = self.token_file.read_text().strip()
        self.read_token = self.read_token_file.read_text().strip()

    def auth(self, read: bool = False) -> dict[str, str]:
        """The ``Authorization`` header of the control (or the read-only) token."""
        return {"Authorization": f"Bearer {self.read_token if read else self.token}"}

    def _read(self):
        for line in self.proc.stderr:
            self.lines.append(line.rstrip("\n"))
            if line.startswith(OPEN):       # the last line of its start
                self._serving.set()
        self._serving.set()      # exited: wake the waiter

    def stop(self, timeout: float = 30.0) -> int:
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._reader.join(5)
        return self.proc.returncode


@contextlib.contextmanager
def daemon_and_web(tmp: Path, daemon_args: tuple[str, ...] = (), **web_kwargs):
    """A real ``rigd run`` (:func:`start_daemon`, with ``daemon_args``) and a real ``rigd web``
    in front of it on ``tmp`` (``web_kwargs`` go to :class:`WebProcess`); yields
    ``(daemon, web)`` and stops both (``web.proc.returncode`` tells how ``rigd web`` ended)."""
    d = start_daemon(tmp, daemon_args)
    try:
        web = WebProcess(tmp, d.sock, tmp / "runs", config_folder(tmp), **web_kwargs)
        try:
            yield d, web
        finally:
            web.stop()
    finally:
        d.stop()


def hang_report(d: Daemon) -> str:
    """The daemon's side of a hang (:meth:`Daemon.hang_report`), or why it could not be had."""
    try:
        return d.hang_report()
    except Exception as exc:  # noqa: BLE001 - a report must not hide the failure it explains
        return f"(no daemon report: {exc!r})"


def wait_for(cond, timeout=30.0, interval=0.1, what="condition"):
    """Poll ``cond()`` until truthy (returned) or fail after ``timeout`` s; ``what`` names
    the condition in the failure (a callable is called then, to say the last state seen)."""
    end = time.monotonic() + timeout
    while True:
        v = cond()
        if v:
            return v
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what() if callable(what) else what}")
        time.sleep(interval)


def sse_events(lines, limit=None):
    """``(event name or None, data)`` pairs parsed from Server-Sent-Event ``lines``; stops
    after ``limit`` events when given."""
    name = None
    n = 0
    for line in lines:
        if line.startswith("event: "):
            name = line[7:]
        elif line.startswith("data: "):
            yield name, json.loads(line[6:])
            name = None
            n += 1
            if limit is not None and n >= limit:
                return
