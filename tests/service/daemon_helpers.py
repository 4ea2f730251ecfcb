"""Start the real daemon (`rigd run`) as a process with a real NOTIFY_SOCKET; `rigd ctl` it."""

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
RIGD = str(Path(sys.executable).parent / "rigd")

#: hang bound, s, for waits on another process's start-up or reply (READY, a `rigd ctl` call,
#: a respawned socket process). Only a hang should reach it: on the shared 2-core machine at
#: load average 25 (eight engineers' tests plus under-load), `rigd run --lockstep --duration 1`
#: took 375 s of wall time for 19.5 s of CPU, and a daemon's READY (its socket process
#: started, niced +10) more than the 90 s this was.
PROCESS_S = 600.0


def make_config(tmp_path, **sections):
    """config/sim.yaml with test overrides. The overrun-storm limit is raised: the test host is
    shared and its scheduling jitter is not what these tests are about (the overrun storm
    fault has its own test). So is the stall bound, to 1 s (the derived 18 ms is about the
    plant; a shared test machine stalls a loop that long now and then): loop_stall has its
    own tests (tests/faults/test_faults_liveness.py, tests/loop/test_liveness.py). The loop
    sleeps to each deadline (``clock.spin_us`` 0, no busy-wait): these tests are about what
    the daemon does, not its deadline precision (tests/loop/test_timing_histogram.py), and a
    spinning SCHED_FIFO daemon takes half a core from every test beside it."""
    cfg = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    cfg["clock"]["spin_us"] = 0.0
    cfg["supervisor"]["overrun_storm_count"] = 10**9
    cfg["supervisor"]["stall_s"] = 1.0
    cfg["recorder"]["data_dir"] = str(tmp_path / "data")
    for k, v in sections.items():
        if isinstance(v, dict):
            cfg.setdefault(k, {}).update(v)
        else:
            cfg[k] = v
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def _ignore_sigxfsz():
    """In the child: a write beyond RLIMIT_FSIZE fails (EFBIG) instead of the kernel killing
    the process with SIGXFSZ; the ignore survives exec."""
    import signal

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


class Daemon:
    def __init__(self, tmp_path, config, *extra, watchdog_usec=400000, fsize_limit=False,
                 preexec=None):
        self.tmp = Path(tmp_path)
        self.sock = str(self.tmp / "rigd.sock")
        self.notify_path = str(self.tmp / "notify.sock")
        self.notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.notify.bind(self.notify_path)
        self.messages = []
        self._closing = False
        self.notify.settimeout(0.2)
        self._reader = threading.Thread(target=self._collect, daemon=True)
        self._reader.start()
        env = dict(os.environ, NOTIFY_SOCKET=self.notify_path, PYTHONFAULTHANDLER="1",
                   WATCHDOG_USEC=str(watchdog_usec))
        env.pop("WATCHDOG_PID", None)
        self.stderr = open(self.tmp / "daemon.err", "w")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(
            [RIGD, "run", "--config", str(config), "--socket", self.sock,
             "--runs-dir", str(self.tmp / "runs"), *extra],
            stdout=subprocess.PIPE, stderr=self.stderr, text=True, env=env, cwd=str(self.tmp),
            preexec_fn=preexec or (_ignore_sigxfsz if fsize_limit else None))

    def writer_pid(self):
        """The daemon's HDF5 writer process (``status`` → ``recorder.writer_pid``), or None."""
        return self.ctl_json("status")["recorder"]["writer_pid"]

    def limit_fsize(self, nbytes, writer_pid=None):
        """From now on no file of the daemon may grow beyond ``nbytes`` (RLIMIT_FSIZE set on
        the running daemon and on its HDF5 writer process ``writer_pid``, from
        :meth:`writer_pid` *before* the size is chosen: a `rigd ctl` call takes seconds on a
        busy machine, while the file grows): a full disk, as the writer sees it — write()
        fails with EFBIG. Set after start-up, not in the child before exec: the recorder's
        ring is a memfd of about 80 MB, whose ftruncate the limit would refuse. Needs
        ``fsize_limit=True`` (the writer process ignores SIGXFSZ itself)."""
        import resource

        for pid in (self.proc.pid, writer_pid):
            if pid is not None:
                resource.prlimit(pid, resource.RLIMIT_FSIZE, (nbytes, nbytes))

    def _collect(self):
        """Read NOTIFY_SOCKET all the time, as systemd does."""
        while True:
            try:
                m = self.notify.recv(4096).decode()
            except TimeoutError:
                if self._closing:
                    return
                continue
            except OSError:
                return
            self.messages.append(m)

    def wait_notify(self, needle, timeout=PROCESS_S):
        """Wait until a notify datagram containing ``needle`` has arrived."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for m in list(self.messages):
                if needle in m:
                    return m
            if self.proc.poll() is not None:
                break
            time.sleep(0.02)
        for m in list(self.messages):
            if needle in m:
                return m
        raise AssertionError(f"no {needle!r} in {self.messages}; exit {self.proc.poll()}; "
                             f"log: {self.log()}")

    def ctl(self, *args, check=True):
        r = subprocess.run([RIGD, "ctl", "--socket", self.sock, *args], capture_output=True,
                           text=True, timeout=PROCESS_S)
        if check:
            assert r.returncode == 0, (args, r.stderr)
        return r

    def ctl_json(self, *args):
        return json.loads(self.ctl(*args, "--json").stdout)

    def log(self):
        if not self.stderr.closed:
            self.stderr.flush()
        return (self.tmp / "daemon.err").read_text()[-3000:]

    def processes(self):
        """The daemon and its descendants as ``(pid, name, state)`` (from /proc)."""
        parent = {}
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    stat = (d / "stat").read_text()
                except OSError:
                    continue
                head, rest = stat.rsplit(")", 1)
                fields = rest.split()
                parent[int(d.name)] = (int(fields[1]), head.split("(", 1)[1], fields[0])
        out, todo = [], [self.proc.pid]
        while todo:
            pid = todo.pop()
            if pid in parent:
                out.append((pid, parent[pid][1], parent[pid][2]))
            todo += [p for p, (pp, _, _) in parent.items() if pp == pid]
        return out

    def hang_report(self, wait_s=2.0):
        """What a hang bound says of the daemon: ``experiment`` and ``status`` as `rigd ctl`
        sees them, its processes (pid, name, state) and the tail of its stderr after every
        thread's stack of each of its Python processes was dumped there (SIGUSR2, sent only to
        the processes that handle it: the daemon and the processes it spawned)."""
        lines = []
        for args in (("experiment",), ("status",)):
            try:
                r = subprocess.run([RIGD, "ctl", "--socket", self.sock, *args, "--json"],
                                   capture_output=True, text=True, timeout=60)
                lines.append(f"rigd ctl {args[0]}: {(r.stdout or r.stderr).strip()[:1500]}")
            except subprocess.TimeoutExpired:
                lines.append(f"rigd ctl {args[0]}: no answer in 60 s")
        procs = self.processes()
        lines.append(f"daemon processes: {procs}")
        for pid, _, _ in procs:
            try:
                caught = next(x for x in Path(f"/proc/{pid}/status").read_text().splitlines()
                              if x.startswith("SigCgt:"))
                if int(caught.split()[1], 16) >> (signal.SIGUSR2 - 1) & 1:
                    os.kill(pid, signal.SIGUSR2)
            except (OSError, StopIteration, ValueError):
                pass
        time.sleep(wait_s)
        if not self.stderr.closed:
            self.stderr.flush()
        lines.append("daemon stderr (tail):\n"
                     + (self.tmp / "daemon.err").read_text(errors="replace")[-20000:])
        return "\n".join(lines)

    def stop(self, sig=15, timeout=60):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            out, _ = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.send_signal(6)  # SIGABRT: faulthandler dumps every thread to daemon.err
            self.proc.communicate(timeout=10)
            raise AssertionError(f"daemon did not stop within {timeout} s: {self.log()}") from None
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            self._closing = True
            self._reader.join(5)  # returns after draining what the daemon sent before exit
            self.notify.close()
            self.stderr.close()
        return self.proc.returncode, out
