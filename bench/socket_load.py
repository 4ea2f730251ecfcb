"""Control-socket load test: does a flood of requests disturb the 5 kHz loop?

A real daemon (``rigd run`` on the simulated rig, real-time clock) is started; its loop's
real-time miss fraction (overruns per cycle, from ``timing``) is measured over ``seconds``
idle, then over ``seconds`` while ``clients`` connections send ``rate`` requests/s in total —
a mix of ``status``/``timing``/``faults``/``ping``, malformed JSON, unknown commands, bad
arguments and oversized lines. Every reply is checked.

Figures (keys of ``run()``): ``socket_load_rt_miss_fraction_idle``,
``socket_load_rt_miss_fraction_loaded``, ``socket_load_requests_served``,
``socket_load_requests_per_s``, ``socket_load_bad_requests_refused``,
``socket_load_errors`` (wrong or missing replies: must be 0), ``socket_load_reply_p99_ms``,
``socket_load_rt_miss_fraction_control``: the same load aimed at a separate server process
(not the daemon; same server code, niceness and reply sizes: it serves the daemon's own
answers, taken once) — what the load costs the loop through the machine alone (CPU, kernel), the
yardstick for ``..._loaded``; ``..._idle`` is the mean of an idle window before and after.

``socket_busy_status_ms`` {p50, p99, max}: ``status`` latency while a slow command is pending
(target p99 <= 50 ms). The daemon side of the socket (:class:`rigd.service.bridge.SocketFrontend`,
spawning the real socket process) runs in this process in front of a stub loop whose
``controller.load`` takes ``slow_s`` = 2 s; ``loads`` such loads are sent one after the other
while 20 clients hammer the socket (queries, bad requests and 10 % commands, which queue
behind the load) and a probe asks ``status`` every 10 ms while a load is pending
(``socket_busy_status_n`` probes). Before the forwarding was made asynchronous, each of them
waited for the load. Every load is accounted for: ``socket_busy_loads_applied``,
``socket_busy_loads_refused`` (the reasons) and ``socket_busy_loads_lost`` (no answer within
its deadline: must be 0); every wait of the part is bounded.

    python -m bench socket_load        # about 70 s
"""

from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
RIGD = str(Path(sys.executable).parent / "rigd")

#: (request line, expected ok, expected error substring) — the malformed part of the mix
BAD = [
    (b"not json at all", "not JSON"),
    (b"[1, 2, 3]", "JSON object"),
    (b'{"id": 1}', "no 'cmd'"),
    (b'{"id": 1, "cmd": "reboot"}', "unknown command"),
    (b'{"id": 1, "cmd": "status", "verbose": true}', "unknown argument"),
    (b'{"id": 1, "cmd": "operating_point.set", "omega_rpm": "x", "p_inj_bar": 4}', "omega_rpm"),
    (b'{"id": 1, "cmd": "controller.load", "path": "rel.yaml"}', "absolute"),
    (b"\xff\xfe\xfd", "UTF-8"),
]
GOOD = ["status", "timing", "faults", "ping", "experiment.status"]
#: error replies that are a correct answer to a valid command under load (refused, not run)
BUSY_REFUSALS = ("too many commands", "already waiting")


def _config(tmp: Path) -> Path:
    cfg = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    cfg["supervisor"]["overrun_storm_count"] = 10**9   # measure misses, do not trip on them
    cfg["recorder"]["data_dir"] = str(tmp / "data")
    p = tmp / "rig.yaml"
    p.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return p


def _call(sock_path: str, cmd: str, timeout: float = 10.0) -> dict:
    """One request on a connection of its own; its ``result`` (an error reply or a closed
    connection raises RuntimeError naming the command)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout)
        s.connect(sock_path)
        s.sendall((json.dumps({"id": 1, "cmd": cmd}) + "\n").encode())
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                raise RuntimeError(f"{cmd}: the daemon closed the connection")
            buf += chunk
    reply = json.loads(buf)
    if not reply.get("ok"):
        raise RuntimeError(f"{cmd}: {reply.get('error')}")
    return reply["result"]


def _counts(sock_path: str) -> tuple[int, int]:
    t = _call(sock_path, "timing")
    return int(t["cycles"]), int(t["overruns"])


class _Client(threading.Thread):
    def __init__(self, sock_path, rate, until, seed, commands=0.0, min_requests=0):
        super().__init__(daemon=True)
        self.sock_path, self.rate, self.until = sock_path, rate, until
        self.commands = commands
        self.min_requests = min_requests
        self.rng = random.Random(seed)
        self.served = self.refused = self.errors = 0
        self.latency: list[float] = []
        #: what each error was (request kind, exception or reply, seconds since the request)
        self.error_texts: list[str] = []

    def _reply(self, s, buf):
        while b"\n" not in buf:
            chunk = s.recv(65536)
            if not chunk:
                raise ConnectionError("closed")
            buf += chunk
        line, buf = buf.split(b"\n", 1)
        return json.loads(line), buf

    def run(self):
        period = 1.0 / self.rate
        nxt = time.monotonic()
        s = None
        buf = b""
        rid = 0
        while (time.monotonic() < self.until
               or self.served + self.refused + self.errors < self.min_requests):
            try:
                if s is None:
                    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                    s.settimeout(10)
                    s.connect(self.sock_path)
                    buf = b""
                rid += 1
                r = self.rng.random()
                kind = "?"
                rep = None
                t0 = time.perf_counter()
                if r < 0.02:  # oversized line: refused, connection closed by the daemon
                    kind = "oversized"
                    s.sendall(b"x" * (70 * 1024) + b"\n")
                    rep, buf = self._reply(s, buf)
                    ok = rep["ok"] is False and "longer than" in rep["error"]
                    s.close()
                    s = None
                    self.refused += ok
                elif r < 0.25:  # malformed / bad request: error reply, connection kept
                    line, needle = self.rng.choice(BAD)
                    kind = f"bad {line[:40]!r}"
                    s.sendall(line + b"\n")
                    rep, buf = self._reply(s, buf)
                    ok = rep["ok"] is False and needle in rep["error"]
                    self.refused += ok
                elif r < 0.25 + self.commands:  # a valid command, forwarded to the daemon
                    kind = "operating_point.set"
                    s.sendall((json.dumps({"id": rid, "cmd": "operating_point.set",
                                           "omega_rpm": 1000.0 + self.rng.random(),
                                           "p_inj_bar": 4.0}) + "\n").encode())
                    rep, buf = self._reply(s, buf)
                    ok = rep.get("id") == rid and (rep.get("ok") is True or any(
                        m in rep.get("error", "") for m in BUSY_REFUSALS))
                    self.served += ok
                else:
                    cmd = self.rng.choice(GOOD)
                    kind = cmd
                    s.sendall((json.dumps({"id": rid, "cmd": cmd}) + "\n").encode())
                    rep, buf = self._reply(s, buf)
                    ok = rep.get("ok") is True and rep.get("id") == rid
                    self.served += ok
                self.latency.append(time.perf_counter() - t0)
                if not ok:
                    self.errors += 1
                    self.error_texts.append(f"{kind}: wrong reply {str(rep)[:200]}")
            except (OSError, ValueError, KeyError) as exc:
                self.errors += 1
                self.error_texts.append(f"{kind}: {type(exc).__name__}: {exc} after "
                                        f"{time.perf_counter() - t0:.3f} s")
                if s is not None:
                    s.close()
                s = None
            nxt += period
            d = nxt - time.monotonic()
            if d > 0:
                time.sleep(d)
        if s is not None:
            s.close()


def hammer(sock_path: str, *, clients: int = 20, rate: float = 1000.0,
           seconds: float = 10.0, seed: int = 0, commands: float = 0.0,
           min_requests: int = 0) -> dict:
    """``clients`` connections sending ``rate`` requests/s in total for ``seconds``, and each at
    least ``min_requests`` (however long that takes on a busy machine); a fraction
    ``commands`` of the requests are valid commands (``operating_point.set``)."""
    until = time.monotonic() + seconds
    ts = [_Client(sock_path, rate / clients, until, seed + i, commands, min_requests)
          for i in range(clients)]
    t0 = time.monotonic()
    for t in ts:
        t.start()
    for t in ts:
        t.join(seconds + 30 + min_requests)
    wall = time.monotonic() - t0
    lat = np.concatenate([np.asarray(t.latency) for t in ts]) if ts else np.zeros(1)
    served = sum(t.served for t in ts)
    refused = sum(t.refused for t in ts)
    return {"served": served, "refused": refused, "errors": sum(t.errors for t in ts),
            "error_texts": [e for t in ts for e in t.error_texts][:20],
            "requests_per_s": (served + refused) / wall,
            "reply_p99_ms": float(np.percentile(lat, 99) * 1e3) if lat.size else 0.0}


def start_daemon(tmp: Path, *extra: str, wait_s: float = 120.0
                 ) -> tuple[subprocess.Popen, str]:
    sock = str(tmp / "rigd.sock")
    env = dict(os.environ)
    env.pop("NOTIFY_SOCKET", None)
    with open(tmp / "daemon.err", "w") as err:  # the daemon keeps its own copy
        proc = subprocess.Popen([RIGD, "run", "--config", str(_config(tmp)), "--socket", sock,
                                 *extra], stdout=subprocess.DEVNULL, stderr=err, env=env,
                                cwd=str(tmp))
    end = time.monotonic() + wait_s
    last = "no socket yet (starting: a first start after an edit compiles the numba kernels)"
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise RuntimeError(f"daemon exited: {(tmp / 'daemon.err').read_text()[-2000:]}")
        try:
            seq = _call(sock, "status")["seq"]
            if seq > 5000:
                return proc, sock
            last = f"status answered, cycle {seq} (not yet 5000)"
        except FileNotFoundError:
            pass
        except (OSError, KeyError, ValueError, RuntimeError) as exc:
            last = f"status: {type(exc).__name__}: {exc}"
        time.sleep(0.2)
    proc.kill()
    raise RuntimeError(f"daemon did not come up within {wait_s:g} s ({last}); its log ends: "
                       f"{(tmp / 'daemon.err').read_text()[-1000:]}")


def stop_daemon(proc: subprocess.Popen) -> int:
    proc.send_signal(signal.SIGTERM)
    try:
        return proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()


class _StubLoop:
    """For the control measurement only: answers the queries with fixed data (the daemon's
    own answers, taken once, so replies have the same size and cost the clients the same)."""

    def __init__(self, data: dict):
        self.data = data

    def status(self):
        return self.data["status"]

    def timing(self):
        return self.data["timing"]

    def faults(self):
        return self.data["faults"]


class _StubExperiments:
    def __init__(self, data: dict):
        self.data = data

    def status(self):
        return self.data["experiment"]


def _control_main(path: str, data: dict) -> None:
    """A control-socket server process that is not the daemon (same code, same niceness as the
    daemon's socket process, a stub behind it): the same client load aimed at it shows what
    the load costs the machine, independent of the daemon."""
    import signal as _signal

    from rigd.service.protocol import Dispatcher
    from rigd.service.server import ControlServer

    _signal.signal(_signal.SIGINT, _signal.SIG_IGN)
    os.nice(10)
    info = data["ping"]
    disp = Dispatcher(_StubLoop(data), _StubExperiments(data), info=lambda: info)
    with ControlServer(path, disp.handle_line):
        _signal.sigwait([_signal.SIGTERM])


class _SlowLoop(_StubLoop):
    """For ``busy()``: the loop's command API with a ``load_controller`` that takes ``slow_s``."""

    def __init__(self, data: dict, slow_s: float):
        super().__init__(data)
        self.slow_s = slow_s
        self.pending = threading.Event()

    def load_controller(self, path):
        self.pending.set()
        time.sleep(self.slow_s)          # a slow command (the stand-in for a large validation)
        self.pending.clear()

    def set_operating_point(self, omega_rpm, p_inj_bar):
        pass


def busy(loads: int = 5, slow_s: float = 2.0, clients: int = 20, rate: float = 400.0,
         probe_period_s: float = 0.01) -> dict:
    """``status`` latency while a slow command is pending (see the module docstring)."""
    from rigd.controller import Controller, to_wire
    from rigd.service.bridge import SocketFrontend
    from rigd.service.protocol import Dispatcher

    wire = to_wire(Controller(np.array([[0.5]]), np.zeros((1, 2)), np.zeros((2, 1)),
                              np.zeros((2, 2)), 5000.0))
    data = {"status": {"running": True, "seq": 1}, "timing": {"cycles": 1}, "faults": [],
            "experiment": {"state": "idle"}}
    loop = _SlowLoop(data, slow_s)
    disp = Dispatcher(loop, info=lambda: {"pid": os.getpid()})

    def snapshot():
        return {"status": loop.status(), "timing": loop.timing(), "faults": loop.faults(),
                "info": {"pid": os.getpid()}, "experiment": data["experiment"]}

    lat: list[float] = []
    load_errors = 0
    outcomes: list[dict] = []      # every load: applied, refused (why) or lost
    with tempfile.TemporaryDirectory(prefix="rigd-socket-busy-") as d:
        path = str(Path(d) / "rigd.sock")
        fe = SocketFrontend(path, 0o660, disp.handle_line, snapshot).start()
        try:
            if not fe.ready.wait(60):
                raise RuntimeError("socket process did not come up")
            res: dict = {}
            h = threading.Thread(target=lambda: res.update(hammer(
                path, clients=clients, rate=rate, seconds=loads * (slow_s + 0.3) + 1.0,
                commands=0.1, seed=100)), daemon=True)
            h.start()
            probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            probe.settimeout(30)
            probe.connect(path)
            pbuf = b""
            for i in range(loads):
                a = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                a.settimeout(60)
                a.connect(path)
                # the controller's content, as `rigd ctl load` sends it (no path to open)
                a.sendall((json.dumps({"id": i, "cmd": "controller.load",
                                       "path": "/bench/k.yaml", "controller": wire,
                                       "timeout_s": LOAD_DEADLINE_S}) + "\n").encode())
                # the load reaches the loop, or is answered first (refused), or neither
                # within its deadline (lost): every wait here is bounded
                reply = _await_loop_or_reply(a, loop.pending, LOAD_DEADLINE_S)
                end = time.monotonic() + slow_s + LOAD_DEADLINE_S
                while reply is None and loop.pending.is_set() and time.monotonic() < end:
                    t0 = time.perf_counter()   # sent while the load is pending
                    probe.sendall(b'{"id": 0, "cmd": "status"}\n')
                    line, pbuf = _line(probe, pbuf)
                    dt = time.perf_counter() - t0
                    if json.loads(line).get("ok") is not True:
                        load_errors += 1
                    lat.append(dt)
                    time.sleep(probe_period_s)
                if reply is None:
                    reply = _read_reply(a, LOAD_DEADLINE_S + slow_s)
                outcomes.append(_outcome(reply))
                a.close()
            probe.close()
            h.join(loads * (slow_s + 0.3) + 60)
        finally:
            fe.stop()
    ms = np.asarray(lat) * 1e3 if lat else np.full(1, np.nan)
    applied = sum(o["outcome"] == "applied" for o in outcomes)
    return {"socket_busy_status_ms": {"p50": round(float(np.percentile(ms, 50)), 3),
                                      "p99": round(float(np.percentile(ms, 99)), 3),
                                      "max": round(float(np.max(ms)), 3)},
            "socket_busy_status_n": len(lat),
            "socket_busy_slow_command_s": slow_s,
            "socket_busy_loads_applied": applied,
            "socket_busy_loads_refused": [o["why"] for o in outcomes
                                          if o["outcome"] == "refused"],
            "socket_busy_loads_lost": sum(o["outcome"] == "lost" for o in outcomes),
            "socket_busy_errors": (load_errors + (len(outcomes) - applied)
                                   + res.get("errors", 0)),
            "socket_busy_hammer_requests": res.get("served", 0) + res.get("refused", 0)}


#: deadline of each ``controller.load`` of ``busy()`` (sent as its ``timeout_s``), s: past it
#: the service must have answered (applied or refused); no answer by then is a lost command
LOAD_DEADLINE_S = 30.0


def _line(s: socket.socket, buf: bytes) -> tuple[bytes, bytes]:
    """One reply line from ``s`` (its timeout bounds each read; a closed connection raises)."""
    while b"\n" not in buf:
        chunk = s.recv(65536)
        if not chunk:
            raise ConnectionError("the socket process closed the connection")
        buf += chunk
    line, buf = buf.split(b"\n", 1)
    return line, buf


def _await_loop_or_reply(a: socket.socket, pending: threading.Event,
                         timeout: float) -> dict | None:
    """Wait until the command reached the loop (``pending``: None) or ``a`` got its reply
    first (the reply: refused before the loop), at most ``timeout`` s (None)."""
    import select

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pending.wait(0.005):
            return None
        r, _, _ = select.select([a], [], [], 0)
        if r:
            return _read_reply(a, max(0.1, end - time.monotonic()))
    return None


def _read_reply(a: socket.socket, timeout: float) -> dict | None:
    """The reply on ``a`` within ``timeout`` s, or None (no answer: lost)."""
    a.settimeout(max(timeout, 0.1))
    try:
        line, _ = _line(a, b"")
    except (TimeoutError, OSError):
        return None
    return json.loads(line)


def _outcome(reply: dict | None) -> dict:
    if reply is None:
        return {"outcome": "lost", "why": "no answer within its deadline"}
    if reply.get("ok") is True:
        return {"outcome": "applied", "why": ""}
    return {"outcome": "refused", "why": str(reply.get("error"))}


def _window(sock: str, fn) -> float:
    """rt miss fraction of the daemon while ``fn()`` runs."""
    c0, o0 = _counts(sock)
    fn()
    c1, o1 = _counts(sock)
    return (o1 - o0) / max(c1 - c0, 1)


def run(seconds: float = 10.0, clients: int = 20, rate: float = 1000.0) -> dict:
    """Windows of ``seconds``: idle, loaded (the daemon's socket), control (the same load on a
    separate server process), idle again."""
    import multiprocessing

    with tempfile.TemporaryDirectory(prefix="rigd-socket-load-") as d:
        tmp = Path(d)
        proc, sock = start_daemon(tmp)
        other = str(tmp / "control.sock")
        data = {k: _call(sock, c) for k, c in (("status", "status"), ("timing", "timing"),
                                                ("faults", "faults"), ("ping", "ping"),
                                                ("experiment", "experiment.status"))}
        data["faults"] = data["faults"]["faults"]
        data["ping"].pop("pong", None)
        ctl = multiprocessing.get_context("spawn").Process(target=_control_main,
                                                           args=(other, data))
        ctl.start()
        try:
            while not os.path.exists(other) and ctl.is_alive():
                time.sleep(0.05)
            res = {}
            ran0 = _call(sock, "ping").get("commands_run", 0)
            idle1 = _window(sock, lambda: time.sleep(seconds))
            loaded = _window(sock, lambda: res.update(hammer(sock, clients=clients, rate=rate,
                                                            seconds=seconds)))
            control_load = {}
            control = _window(sock, lambda: control_load.update(
                hammer(other, clients=clients, rate=rate, seconds=seconds)))
            idle2 = _window(sock, lambda: time.sleep(seconds))
            load = res
            ping = _call(sock, "ping")
            alive = ping["pong"]
            reached = ping.get("commands_run", 0) - ran0
        finally:
            code = stop_daemon(proc)
            if ctl.is_alive():
                os.kill(ctl.pid, signal.SIGTERM)
            ctl.join(10)
    return {
        "socket_load_rt_miss_fraction_idle": (idle1 + idle2) / 2,
        "socket_load_rt_miss_fraction_idle_windows": [idle1, idle2],
        "socket_load_rt_miss_fraction_loaded": loaded,
        "socket_load_rt_miss_fraction_control": control,
        "socket_load_control_errors": control_load.get("errors"),
        "socket_load_requests_reaching_loop_process": reached,
        "socket_load_requests_served": load["served"],
        "socket_load_bad_requests_refused": load["refused"],
        "socket_load_requests_per_s": round(load["requests_per_s"], 1),
        "socket_load_reply_p99_ms": round(load["reply_p99_ms"], 3),
        "socket_load_errors": load["errors"],
        "socket_load_clients": clients,
        "socket_load_seconds": seconds,
        "socket_load_daemon_alive_after": bool(alive),
        "socket_load_daemon_exit_code": code,
        **busy(),
    }


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps(busy() if sys.argv[1:] == ["busy"] else run(), indent=2))
