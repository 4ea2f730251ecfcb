"""Web console load: does the live stream to 5 browsers disturb the 5 kHz loop, and how fresh is it?

A real daemon (``rigd run`` on the simulated rig, real-time clock) and a real ``rigd web`` in
front of it (both processes). Windows of ``seconds`` alternate **idle** (nothing connected
but this bench's ``timing`` reads) and **clients** (``clients`` browser-equivalent clients on
``GET /api/stream``, each a process of its own that reads the Server-Sent Events and parses
every ``data:`` JSON, as a page's ``EventSource`` + ``JSON.parse`` do): idle, clients, idle,
clients, idle. The loop's real-time miss fraction (overruns per cycle, from ``timing``) is
measured in each window.

Figures (keys of ``run()``):

* ``web_clients_miss_fraction``: mean over the clients windows (per window in
  ``..._windows``);
* ``web_idle_miss_fraction``: mean over the idle windows of the same run, and
  ``web_idle_miss_fraction_spread`` [min, max] over them: the yardstick (target: the clients
  figure within the idle spread);
* ``web_stream_latency_ms`` {p50, p99, max, n}: per event, the client's receipt (after
  parsing) minus the ``wall_ns`` of the newest sample in it — the time at which the loop
  published that frame, stored before the frame count, so never flattering (target p99 <=
  100 ms); ``web_stream_events_per_s`` per client, ``web_stream_dropped_frames`` (sum of the
  updates' ``dropped``), ``web_stream_bytes_per_event``.

The clients ask for exactly what the console page asks for (``RATE_HZ``, ``POINTS`` and
``CHANNELS`` copied from rigd/web/static/live.js: today 17 channels — orbit e_x/e_y, u_x/u_y,
r_x/r_y, K∞ output k_x/k_y, valve positions y_p1..4 and references r_p1..4, k_on — with
``points`` 20 at ``rate_hz`` 10: 200 min/max buckets a second; 50 updates/s of 4 until
2026-11-27).

Then the console page itself in headless Chromium on the same daemon (bench/console.py):
``console_tab_cpu_percent`` (the tab's renderer process, /proc; target <= 15) with the GPU and
browser processes beside it and where the tab spends it (``console_tab_where``, Chrome's
``Performance.getMetrics``; a CPU profile of it in ``console_tab_profile``),
and ``safe_click_latency_ms`` {p50, p99, max, n} (page click -> latched, on the daemon's cycle
counter, the Live tab drawing; target p99 <= 100), with the load average they were taken at.
That part is bounded by its own budget (10 min; about 1 min idle).

    python -m bench web            # about 2-3 min idle (more on a busy machine)
"""

from __future__ import annotations

import json
import multiprocessing
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.chromium import find_chromium
from bench.console import run as browser_figures
from bench.socket_load import _counts, start_daemon, stop_daemon

ROOT = Path(__file__).resolve().parents[1]
RIGD = str(Path(sys.executable).parent / "rigd")
APP_JS = ROOT / "rigd" / "web" / "static" / "live.js"


def page_subscription() -> tuple[float, int, list[str]]:
    """``RATE_HZ``, ``POINTS`` and ``CHANNELS`` of the console page (rigd/web/static/live.js):
    the bench's clients ask for exactly what a browser showing the console asks for."""
    js = APP_JS.read_text()
    m_r = re.search(r"const RATE_HZ\s*=\s*(\d+(?:\.\d*)?)", js)
    m_p = re.search(r"const POINTS\s*=\s*(\d+)", js)
    m_c = re.search(r"const CHANNELS\s*=\s*\[([^\]]*)\]", js)
    if not (m_r and m_p and m_c):
        raise RuntimeError(f"{APP_JS}: no 'const RATE_HZ' / 'const POINTS' / 'const CHANNELS' "
                           "to copy")
    return float(m_r.group(1)), int(m_p.group(1)), re.findall(r'"([a-z_0-9]+)"', m_c.group(1))


def _client_main(url: str, token: str, go, stop, out) -> None:
    """One browser-equivalent client (a process): read the SSE stream (with the token: every
    read needs one), parse every event, keep the latencies of the events received while
    ``go`` is set."""
    import httpx2 as httpx

    lat, dropped, nbytes, n = [], 0, 0, 0
    ready = True
    try:
        with httpx.stream("GET", url, timeout=httpx.Timeout(30.0, read=30.0),
                          headers={"Authorization": f"Bearer {token}"}) as r:
            for line in r.iter_lines():
                if stop.is_set():
                    break
                if not line.startswith("data: "):
                    continue
                msg = json.loads(line[6:])
                now = time.time_ns()
                if "wall_ns" not in msg:
                    continue
                if ready is not None:        # the first update: tell the bench
                    out.put("ready")
                    ready = None
                if not go.is_set():
                    continue
                lat.append((now - msg["wall_ns"]) / 1e6)
                dropped += msg["dropped"]
                nbytes += len(line)
                n += 1
        out.put({"lat": lat, "dropped": dropped, "bytes": nbytes, "n": n, "error": None})
    except Exception as exc:  # noqa: BLE001 - reported in the figures
        out.put({"lat": lat, "dropped": dropped, "bytes": nbytes, "n": n,
                 "error": f"{type(exc).__name__}: {exc}"})


def _start_web(tmp: Path, sock: str, wait_s: float = 60.0, *extra: str
               ) -> tuple[subprocess.Popen, str]:
    """``rigd web`` (with ``extra`` arguments) in front of ``sock``: (process, its URL)."""
    (tmp / "runs").mkdir(exist_ok=True)
    err = open(tmp / "web.err", "w+")  # noqa: SIM115 - closed with the process
    proc = subprocess.Popen([RIGD, "web", "--socket", sock, "--listen", "127.0.0.1:0",
                             "--runs-dir", str(tmp / "runs"), "--config-dir",
                             str(ROOT / "config"), "--token-file", str(tmp / "token"), *extra],
                            stdout=subprocess.DEVNULL, stderr=err, cwd=str(tmp))
    proc.err = err
    end = time.monotonic() + wait_s
    while time.monotonic() < end:
        err.seek(0)
        m = re.search(r"serving (http://[0-9.]+:\d+)/", err.read())
        if m:
            return proc, m.group(1)
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    alive = proc.poll() is None
    proc.kill()
    err.seek(0)
    why = f"not serving after {wait_s:g} s" if alive else "exited"
    raise RuntimeError(f"rigd web did not start ({why}): {err.read()[-2000:]}")


def _window(sock: str, seconds: float) -> float:
    c0, o0 = _counts(sock)
    time.sleep(seconds)
    c1, o1 = _counts(sock)
    return (o1 - o0) / max(c1 - c0, 1)


def run(seconds: float = 8.0, clients: int = 5, rate_hz: float | None = None) -> dict:
    """Idle / clients / idle / clients / idle windows of ``seconds`` (module docstring);
    ``rate_hz`` None: the page's."""
    page_rate, points, channels = page_subscription()
    rate_hz = page_rate if rate_hz is None else rate_hz
    ctx = multiprocessing.get_context("spawn")
    with tempfile.TemporaryDirectory(prefix="rigd-web-bench-") as d:
        tmp = Path(d)
        daemon, sock = start_daemon(tmp, wait_s=300.0)   # minutes on a busy machine
        web = None
        procs = []
        try:
            web, base = _start_web(tmp, sock, wait_s=300.0)
            token = (tmp / "token").read_text().strip()
            url = (f"{base}/api/stream?rate_hz={rate_hz:g}&points={points}"
                   f"&channels={','.join(channels)}")
            idle, busy = [], []
            results = []
            for k in range(5):
                if k % 2 == 0:
                    idle.append(_window(sock, seconds))
                    continue
                go, stop, out = ctx.Event(), ctx.Event(), ctx.Queue()
                procs = [ctx.Process(target=_client_main, args=(url, token, go, stop, out),
                                     daemon=True) for _ in range(clients)]
                for p in procs:
                    p.start()
                for _ in procs:               # every client has had its first update
                    if out.get(timeout=300) != "ready":
                        raise RuntimeError("a stream client failed before its first update")
                go.set()
                t0 = time.monotonic()
                busy.append(_window(sock, seconds))
                span = time.monotonic() - t0
                go.clear()
                stop.set()
                for _ in procs:
                    r = out.get(timeout=60)
                    r["span"] = span
                    results.append(r)
                for p in procs:
                    p.join(10)
                    if p.is_alive():
                        p.kill()
                procs = []
            alive = bool(_counts(sock)[0])
            # the page itself in headless Chromium: one tab's CPU, SAFE click -> latched
            if find_chromium()[1]:
                console = browser_figures(base, (tmp / "token").read_text().strip(), sock)
            else:
                console = {"console_skipped": "chromium/chromedriver not installed"}
        finally:
            for p in procs:
                if p.is_alive():
                    p.kill()
            if web is not None:
                web.terminate()
                try:
                    web.wait(10)
                except subprocess.TimeoutExpired:
                    web.kill()
                    web.wait()
                web.err.close()
            code = stop_daemon(daemon)
    lat = np.concatenate([np.asarray(r["lat"], float) for r in results]) if results else []
    n = sum(r["n"] for r in results)
    return {
        "web_clients_miss_fraction": float(np.mean(busy)),
        "web_clients_miss_fraction_windows": busy,
        "web_idle_miss_fraction": float(np.mean(idle)),
        "web_idle_miss_fraction_windows": idle,
        "web_idle_miss_fraction_spread": [float(min(idle)), float(max(idle))],
        "web_stream_latency_ms": {
            "p50": round(float(np.percentile(lat, 50)), 2) if n else None,
            "p99": round(float(np.percentile(lat, 99)), 2) if n else None,
            "max": round(float(np.max(lat)), 2) if n else None, "n": int(n)},
        "web_stream_events_per_s": round(n / max(sum(r["span"] for r in results), 1e-9), 1),
        "web_stream_dropped_frames": int(sum(r["dropped"] for r in results)),
        "web_stream_bytes_per_event": round(sum(r["bytes"] for r in results) / max(n, 1)),
        "web_stream_client_errors": [r["error"] for r in results if r["error"]],
        "web_clients": clients, "web_rate_hz": rate_hz, "web_points": points,
        "web_channels": channels, "web_seconds": seconds,
        "web_daemon_alive_after": alive, "web_daemon_exit_code": code,
        **console,
    }


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps(run(), indent=2))
    os._exit(0)
