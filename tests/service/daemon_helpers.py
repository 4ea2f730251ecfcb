"""Start the real daemon (`rigd run`) as a process with a real NOTIFY_SOCKET; `rigd ctl` it."""

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
RIGD = str(Path(sys.executable).parent / "rigd")


def make_config(tmp_path, **sections):
    """config/sim.yaml with test overrides. The overrun-storm limit is raised: the test host is
    shared and its scheduling jitter is not what these tests are about (the overrun storm
    fault has its own test)."""
    cfg = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    cfg["supervisor"]["overrun_storm_count"] = 10**9
    cfg["recorder"]["data_dir"] = str(tmp_path / "data")
    for k, v in sections.items():
        if isinstance(v, dict):
            cfg.setdefault(k, {}).update(v)
        else:
            cfg[k] = v
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


class Daemon:
    def __init__(self, tmp_path, config, *extra, watchdog_usec=400000):
        self.tmp = Path(tmp_path)
        self.sock = str(self.tmp / "rigd.sock")
        self.notify_path = str(self.tmp / "notify.sock")
        self.notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.notify.bind(self.notify_path)
        self.messages = []
        env = dict(os.environ, NOTIFY_SOCKET=self.notify_path,
                   WATCHDOG_USEC=str(watchdog_usec))
        env.pop("WATCHDOG_PID", None)
        self.stderr = open(self.tmp / "daemon.err", "w")
        self.proc = subprocess.Popen(
            [RIGD, "run", "--config", str(config), "--socket", self.sock,
             "--runs-dir", str(self.tmp / "runs"), *extra],
            stdout=subprocess.PIPE, stderr=self.stderr, text=True, env=env, cwd=str(self.tmp))

    def wait_notify(self, needle, timeout=90.0):
        """Collect notify datagrams until one contains ``needle``."""
        end = time.monotonic() + timeout
        for m in self.messages:
            if needle in m:
                return m
        while time.monotonic() < end:
            if self.proc.poll() is not None and needle != "STOPPING=1":
                raise AssertionError(f"daemon exited {self.proc.returncode}: {self.log()}")
            self.notify.settimeout(0.5)
            try:
                m = self.notify.recv(4096).decode()
            except socket.timeout:
                continue
            self.messages.append(m)
            if needle in m:
                return m
        raise AssertionError(f"no {needle!r} in {self.messages}; log: {self.log()}")

    def ctl(self, *args, check=True):
        r = subprocess.run([RIGD, "ctl", "--socket", self.sock, *args], capture_output=True,
                           text=True, timeout=60)
        if check:
            assert r.returncode == 0, (args, r.stderr)
        return r

    def ctl_json(self, *args):
        return json.loads(self.ctl(*args, "--json").stdout)

    def log(self):
        if not self.stderr.closed:
            self.stderr.flush()
        return (self.tmp / "daemon.err").read_text()[-3000:]

    def stop(self, sig=15, timeout=60):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            out, _ = self.proc.communicate(timeout=timeout)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            self.notify.setblocking(False)
            while True:  # datagrams sent before the exit are still queued
                try:
                    self.messages.append(self.notify.recv(4096).decode())
                except BlockingIOError:
                    break
            self.notify.close()
            self.stderr.close()
        return self.proc.returncode, out
