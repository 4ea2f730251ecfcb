"""The console page in a real browser (headless Chromium, bench/chromium.py) on a real daemon
and ``rigd web``: what one tab costs, and how fast a SAFE click lands while it draws.

Figures (keys of :func:`run`, part of ``python -m bench web``):

* ``console_tab_cpu_percent``: CPU of the tab's renderer process (utime + stime from
  ``/proc/<pid>/stat``) over ``seconds`` of the Live tab streaming (50 updates/s) and drawing,
  as a percentage of one core (target <= 15). ``console_gpu_process_cpu_percent``: the same for
  Chromium's GPU process, which rasterises the WebGL traces on the CPU here (no GPU: the
  software rasterizer), reported beside it so that the renderer's figure does not hide it.
* ``safe_click_latency_ms`` {p50, p99, max, n}: per click on the page's SAFE button (a real
  pointer click through WebDriver) with the Live tab drawing, the cycle at which the daemon
  latched ``operator_safe`` (its fault ``seq``) minus the cycle the loop was at when the page
  took the click, over the loop rate. The click's cycle is the page's: the newest streamed
  update's ``seq`` advanced by the wall time from that update's ``wall_ns`` (published by the
  loop) to the click's ``performance.timeOrigin + now()`` at 5 kHz (target p99 <= 100 ms).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.chromium import make_driver
from bench.socket_load import _call, start_daemon, stop_daemon

TICK = os.sysconf("SC_CLK_TCK")


def _children(pid: int) -> list[int]:
    """Every descendant of ``pid`` (from the parent ids in /proc/*/stat)."""
    parent: dict[int, int] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            parent[int(d.name)] = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        kids = [k for k, pp in parent.items() if pp == p]
        out.extend(kids)
        todo.extend(kids)
    return out


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def _chromium_procs(service) -> dict[str, list[int]]:
    """Chromium's processes under the driver: ``{"renderer": [...], "gpu": [...]}``."""
    out: dict[str, list[int]] = {"renderer": [], "gpu": []}
    for p in _children(service.process.pid):
        try:
            cmd = Path(f"/proc/{p}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"--type=renderer" in cmd:
            out["renderer"].append(p)
        elif b"--type=gpu-process" in cmd:
            out["gpu"].append(p)
    return out


def _cpu_percent(pids: list[int], seconds: float) -> tuple[float, list[float]]:
    """(the busiest process's CPU %, every one's) over ``seconds`` of wall time."""
    a = {p: _cpu_s(p) for p in pids}
    t0 = time.monotonic()
    time.sleep(seconds)
    dt = time.monotonic() - t0
    per = [100.0 * (_cpu_s(p) - a[p]) / dt for p in pids]
    return (max(per) if per else float("nan")), per


def _wait(cond, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    raise RuntimeError(f"timed out waiting for {what}")


def run(base: str, token: str, sock: str, seconds: float = 20.0, clicks: int = 10) -> dict:
    """The console figures against ``rigd web`` at ``base`` (module docstring)."""
    driver, service = make_driver()
    try:
        driver.get(base + "/")
        driver.execute_script("sessionStorage.setItem('rigd-token', arguments[0])", token)
        driver.get(base + "/")
        _wait(lambda: driver.execute_script("return window.rigd.mode === 'stream' && "
                                            "window.rigd.renders > 2"), 300, "page live")
        procs = _chromium_procs(service)
        tab, per_renderer = _cpu_percent(procs["renderer"], seconds)
        gpu = _cpu_percent(procs["gpu"], seconds)[0] if procs["gpu"] else None
        lat = []
        safe = driver.find_element("id", "safe")
        for k in range(clicks):
            _call(sock, "fault.reset")
            _wait(lambda: not driver.execute_script(
                "const s = window.rigd.lastStatus; return s && s.fault && s.fault.code"), 60,
                "fault cleared on the page")
            n0 = driver.execute_script("return window.rigd.renders")
            _wait(lambda n0=n0: driver.execute_script("return window.rigd.renders") > n0, 60,
                  "the page drawing")
            safe.click()
            st = _wait(lambda: (lambda s: s if s["fault"]["code"] else None)(
                _call(sock, "status")), 60, "SAFE latched")
            c = driver.execute_script(f"return window.rigd.safeClicks[{k}]")
            fs = driver.execute_script("return window.rigd.fs")
            seq_click = c["seq"] + (c["wall_ms"] * 1e6 - c["wall_ns"]) * fs / 1e9
            lat.append((st["fault"]["seq"] - seq_click) / fs * 1e3)
        _call(sock, "fault.reset")
    finally:
        driver.quit()
        service.stop()
    la = np.asarray(lat)
    return {
        "console_tab_cpu_percent": round(tab, 1),
        "console_renderer_cpu_percent_each": [round(x, 1) for x in per_renderer],
        "console_gpu_process_cpu_percent": None if gpu is None else round(gpu, 1),
        "console_cpu_seconds": seconds,
        "safe_click_latency_ms": {"p50": round(float(np.percentile(la, 50)), 1),
                                  "p99": round(float(np.percentile(la, 99)), 1),
                                  "max": round(float(la.max()), 1), "n": len(lat)},
        "load_average": [round(x, 2) for x in os.getloadavg()],
    }


def main(seconds: float = 20.0, clicks: int = 10) -> dict:
    """A daemon and ``rigd web`` of their own, then :func:`run`."""
    from bench.web import _start_web

    with tempfile.TemporaryDirectory(prefix="rigd-console-bench-") as d:
        tmp = Path(d)
        daemon, sock = start_daemon(tmp)
        web = None
        try:
            web, base = _start_web(tmp, sock)
            token = (tmp / "token").read_text().strip()
            return run(base, token, sock, seconds, clicks)
        finally:
            if web is not None:
                web.terminate()
                web.wait(30)
                web.err.close()
            stop_daemon(daemon)


if __name__ == "__main__":  # pragma: no cover
    import json

    print(json.dumps(main(), indent=2))
    os._exit(0)
