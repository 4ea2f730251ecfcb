"""The console page in a real browser (headless Chromium, bench/chromium.py) on a real daemon
and ``rigd web``: what one tab costs, where it spends it, and how fast a SAFE click lands while
it draws.

Figures (keys of :func:`run`, part of ``python -m bench web``):

* ``console_tab_cpu_percent``: CPU of the tab's renderer process (utime + stime from
  ``/proc/<pid>/stat``) over ``seconds`` of the Live tab streaming (the page's subscription:
  10 updates/s of 20 buckets) and drawing,
  as a percentage of one core (target <= 15), the page as a user gets it (its lines and bars
  on its own canvas over Plotly's frames: rigd/web/static/canvas.js), once it has settled:
  the window starts when every live plot has been drawn (orbit, traces, trends, cycle-time
  percentiles and histogram) and ``SETTLE_S`` later. ``console_tab_cpu_percent_settling`` is
  the same renderer over those ``SETTLE_S`` s: the page's first Plotly frames (the histogram's
  and the trends' first layouts, the traces' axes re-ranging as their first 2 s fill), the
  JIT compiling the page — a one-off of the page's start, apart from the steady figure (5 s
  windows from the first draws, load average 8-13: 9-13 % in the first two, 5-7 % after;
  the window used to start right after the first draws).
  Beside it, over the same window: ``console_gpu_process_cpu_percent`` (Chromium's GPU
  process: it composites and rasterises the tab's pixels — on the CPU here, no GPU) and
  ``console_browser_process_cpu_percent``; ``console_chromium_cpu_percent`` is the sum of the
  three, all the CPU the open tab costs.
* ``console_tab_where``: where the renderer's main thread spends its time, in % of the
  window's wall time — Chrome's own counters (CDP ``Performance.getMetrics``: ``task`` every
  task, of which ``script``, ``layout``, ``style``) and the page's ``draw`` (its drawing,
  ``window.rigd.drawMs``; per plot job in ``draw_by_plot``: ``window.rigd.jobMs``) — with the
  stream ``updates_per_s`` and the redraws per second of the time traces and the orbit.
* ``console_tab_profile``: a CDP sampling profile (``Profiler``) of the renderer's main thread
  over another ``seconds`` of the Live tab: ``self`` the functions with the most self time
  and ``page`` the page's own functions (rigd/web/static/*.js) with their inclusive time, in %
  of the samples (``(idle)`` and ``(program)`` among them: the share spent outside scripts).
* ``safe_click_latency_ms`` {p50, p99, max, n}: per click on the page's SAFE button (a real
  pointer click through WebDriver) with the Live tab drawing, the cycle at which the daemon
  latched ``operator_safe`` (its fault ``seq``) minus the cycle the loop was at when the page
  took the click, over the loop rate. The click's cycle is the page's: the newest streamed
  update's ``seq`` advanced by the wall time from that update's ``wall_ns`` (published by the
  loop) to the click's ``performance.timeOrigin + now()`` at the loop rate (target p99 <= 100).
  Before each click the fault is reset and the page has drawn since; the clicks are
  ``CLICK_GAP_S`` apart (the page sends one SAFE per 0.5 s at most).
* ``console_tab_cpu_percent_50hz``, ``console_tab_where_50hz``,
  ``safe_click_latency_ms_50hz``: the same tab CPU window and SAFE clicks with the page
  opened at ``FAST_QUERY`` (``?rate_hz=50&points=4``): the stream at 50 updates/s, the rate
  issue 22 names for the SAFE figure ("Live tab drawing at 50 Hz"; the page's own rate is 10
  updates/s since ed1b5f9).

Bounded time: the whole section stops with an error naming the step once ``budget_s`` (default
600 s) has passed; on an idle 2-core machine it takes about 3 × ``seconds`` + 2 × ``SETTLE_S``
+ 4 s per click pair + 2 page loads, ≈ 95 s with the defaults.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.chromium import make_driver
from bench.socket_load import _call, start_daemon, stop_daemon

TICK = os.sysconf("SC_CLK_TCK")
#: seconds between two SAFE clicks (the page ignores a second press within 0.5 s)
CLICK_GAP_S = 0.7
#: bound on one control-socket request, s: the daemon's socket process is niced, so on a
#: machine busy with other jobs its answers may take seconds
SOCKET_S = 60.0
#: the page's address for the 50 updates/s measurement (live.js reads rate_hz and points):
#: 4 buckets per update, the same 200 buckets/s as the page's own 10 x 20
FAST_QUERY = "?rate_hz=50&points=4"
#: seconds the page draws after its plots' first draws before the CPU window (module docstring)
SETTLE_S = 10.0
#: Chrome's main-thread counters reported in ``console_tab_where`` (seconds, cumulative)
METRICS = {"task": "TaskDuration", "script": "ScriptDuration", "layout": "LayoutDuration",
           "style": "RecalcStyleDuration"}


class Budget:
    """The section's time bound: ``wait`` raises once the deadline has passed."""

    def __init__(self, seconds: float) -> None:
        self.end = time.monotonic() + seconds
        self.seconds = seconds

    def wait(self, cond, what: str, timeout: float = 120.0):
        from selenium.common.exceptions import TimeoutException

        end = min(self.end, time.monotonic() + timeout)
        while True:
            try:
                v = cond()
            except TimeoutException:      # the renderer too busy to answer this time
                v = None
            if v:
                return v
            if time.monotonic() > end:
                why = (f"the bench's budget of {self.seconds:g} s" if end == self.end
                       else f"{timeout:g} s")
                raise RuntimeError(f"bench console: timed out ({why}) waiting for {what}")
            time.sleep(0.05)

    def left(self) -> float:
        return self.end - time.monotonic()


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
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / TICK


def _chromium_procs(service) -> dict[str, list[int]]:
    """Chromium's processes under the driver: renderers, the GPU process, the browser."""
    out: dict[str, list[int]] = {"renderer": [], "gpu": [], "browser": []}
    for p in _children(service.process.pid):
        try:
            # a zygote-forked child rewrites its title: one string with spaces, not NULs
            cmd = Path(f"/proc/{p}/cmdline").read_bytes().replace(b"\0", b" ")
        except OSError:
            continue
        if b"--type=renderer" in cmd:
            out["renderer"].append(p)
        elif b"--type=gpu-process" in cmd:
            out["gpu"].append(p)
        elif b"--type=" not in cmd and b"chrom" in cmd.split(b" ", 1)[0]:
            out["browser"].append(p)
    return out


def _cdp(driver, cmd: str, params: dict | None = None) -> dict:
    """One Chrome DevTools Protocol command through chromedriver."""
    return driver.execute("executeCdpCommand", {"cmd": cmd, "params": params or {}})["value"]


def _metrics(driver) -> dict[str, float]:
    got = {m["name"]: m["value"] for m in _cdp(driver, "Performance.getMetrics")["metrics"]}
    return {k: float(got.get(v, float("nan"))) for k, v in METRICS.items()}


def _page_counters(driver) -> dict[str, float]:
    return driver.execute_script(
        "const r = window.rigd; return {draw_ms: r.drawMs, updates: r.updates, "
        "traces: r.renders, orbit: r.orbitRenders, jobs: r.jobMs || {}, "
        "layouts: r.frameLayouts || {}};")


def _get(driver, url: str) -> None:
    """Navigate; a page slow to load (seconds to parse Plotly on a machine busy with other
    jobs) is not an error: the waits that follow bound it."""
    from selenium.common.exceptions import TimeoutException

    try:
        driver.get(url)
    except TimeoutException:
        pass


def _open(driver, base: str, query: str, budget: Budget) -> None:
    """The page at ``base/query``, live and drawing: every live plot drawn at least once."""
    _get(driver, base + "/" + query)
    budget.wait(lambda: driver.execute_script(
        "const r = window.rigd; return !!r && r.mode === 'stream' && r.renders > 2 "
        "&& r.orbitRenders > 2 && r.trendRenders > 0 && r.timingRenders > 0 "
        "&& r.histRenders > 0"), "the page live and every plot drawn")
    _cdp(driver, "Performance.enable")


def _window(driver, service, seconds: float) -> dict:
    """CPU of Chromium's processes and the tab's main-thread counters over ``seconds``."""
    procs = _chromium_procs(service)
    pids = [p for ps in procs.values() for p in ps]
    c0 = {p: _cpu_s(p) for p in pids}
    m0, j0 = _metrics(driver), _page_counters(driver)
    t0 = time.monotonic()
    time.sleep(seconds)
    dt = time.monotonic() - t0
    c1 = {p: _cpu_s(p) for p in pids}
    m1, j1 = _metrics(driver), _page_counters(driver)
    pct = {p: 100.0 * (c1[p] - c0[p]) / dt for p in pids}

    def busiest(kind: str) -> float | None:
        vals = [pct[p] for p in procs[kind] if np.isfinite(pct[p])]
        return round(max(vals), 1) if vals else None

    out = {"renderer": busiest("renderer"), "gpu": busiest("gpu"),
           "browser": busiest("browser")}
    out["sum"] = round(sum(v for v in (out["renderer"], out["gpu"], out["browser"]) if v), 1)
    where = {k: round(100.0 * (m1[k] - m0[k]) / dt, 1) for k in METRICS}
    where["draw"] = round(100.0 * (j1["draw_ms"] - j0["draw_ms"]) / 1e3 / dt, 1)
    where["updates_per_s"] = round((j1["updates"] - j0["updates"]) / dt, 1)
    where["traces_redraws_per_s"] = round((j1["traces"] - j0["traces"]) / dt, 1)
    where["orbit_redraws_per_s"] = round((j1["orbit"] - j0["orbit"]) / dt, 1)
    # the page's drawing per plot job (plots.js JOBS: header, orbit, traces, trends, timing =
    # the cycle-time percentiles, hist = the histogram, its drawing after its fetch), % of the
    # wall time; and the Plotly frames laid out again in the window, per figure (canvas.js
    # plotFrame: each re-range of an axis)
    where["draw_by_plot"] = {k: round(100.0 * (v - j0["jobs"].get(k, 0.0)) / 1e3 / dt, 1)
                             for k, v in j1["jobs"].items() if not k.endswith("_n")}
    where["frame_layouts"] = {k: v - j0["layouts"].get(k, 0) for k, v in j1["layouts"].items()}
    out["where"] = where
    return out


def _profile(driver, seconds: float, top: int = 12) -> dict:
    """The renderer main thread's CPU profile over ``seconds`` (module docstring)."""
    _cdp(driver, "Profiler.enable")
    _cdp(driver, "Profiler.setSamplingInterval", {"interval": 500})     # µs
    _cdp(driver, "Profiler.start")
    time.sleep(seconds)
    prof = _cdp(driver, "Profiler.stop")["profile"]
    _cdp(driver, "Profiler.disable")
    nodes = {n["id"]: n for n in prof["nodes"]}
    parent = {c: n["id"] for n in prof["nodes"] for c in n.get("children", [])}
    counts: dict[int, int] = {}
    for s in prof.get("samples", []):
        counts[s] = counts.get(s, 0) + 1
    total = max(sum(counts.values()), 1)

    def name(n: dict) -> tuple[str, str]:
        cf = n["callFrame"]
        return cf["functionName"] or "(anonymous)", cf["url"].rsplit("/", 1)[-1]

    own: dict[str, int] = {}
    page: dict[str, int] = {}
    for nid, c in counts.items():
        f, url = name(nodes[nid])
        key = f"{f} {url}:{nodes[nid]['callFrame']['lineNumber'] + 1}" if url else f
        own[key] = own.get(key, 0) + c
        seen, x = set(), nid
        while x is not None:                       # inclusive: once per sample and function
            f, url = name(nodes[x])
            if url.endswith(".js") and not url.startswith("plotly") and (f, url) not in seen:
                seen.add((f, url))
                page[f"{f} {url}"] = page.get(f"{f} {url}", 0) + c
            x = parent.get(x)

    def pct(d: dict[str, int]) -> dict[str, float]:
        best = sorted(d.items(), key=lambda kv: -kv[1])[:top]
        return {k: round(100.0 * v / total, 1) for k, v in best}

    return {"self": pct(own), "page": pct(page), "samples": total}


def _clicks(driver, sock: str, clicks: int, budget: Budget) -> list[float]:
    """SAFE clicks with the Live tab drawing: latency in ms per click (module docstring)."""
    lat = []
    safe = driver.find_element("id", "safe")
    fs = driver.execute_script("return window.rigd.fs")
    for k in range(clicks):
        if _call(sock, "status", SOCKET_S)["fault"]["code"]:
            _call(sock, "fault.reset", SOCKET_S)
        budget.wait(lambda: driver.execute_script(
            "const s = window.rigd.lastStatus; return !!s && !(s.fault && s.fault.code)"),
            f"click {k + 1}: the fault cleared on the page", 30)
        n0 = driver.execute_script("return window.rigd.renders")
        budget.wait(lambda n0=n0: driver.execute_script("return window.rigd.renders") > n0,
                    f"click {k + 1}: the page drawing", 30)
        time.sleep(CLICK_GAP_S)          # apart from the previous press (the page's guard)
        n_before = driver.execute_script("return window.rigd.safeClicks.length")
        safe.click()
        c = budget.wait(lambda n=n_before: driver.execute_script(
            f"return window.rigd.safeClicks.length > {n} && window.rigd.safeClicks[{n}]"),
            f"click {k + 1}: the page took it", 30)
        st = budget.wait(lambda: (lambda s: s if s["fault"]["code"] else None)(
            _call(sock, "status", SOCKET_S)), f"click {k + 1}: SAFE latched", 30)
        seq_click = c["seq"] + (c["wall_ms"] * 1e6 - c["wall_ns"]) * fs / 1e9
        lat.append((st["fault"]["seq"] - seq_click) / fs * 1e3)
    _call(sock, "fault.reset", SOCKET_S)
    return lat


def _step_failures() -> tuple[type[BaseException], ...]:
    """What a step of :func:`run` may fail with and still leave the others' figures: a bound
    passed (RuntimeError), a socket error, or a WebDriver command that failed or outlasted
    its own timeout (bench/chromium.py COMMAND_TIMEOUT_S: a click on a renderer starved for
    5 min, seen at load average 20, raised urllib3's ReadTimeoutError and took the whole
    section's JSON with it)."""
    from selenium.common.exceptions import WebDriverException
    from urllib3.exceptions import HTTPError

    return (RuntimeError, OSError, WebDriverException, HTTPError)


def _summary(lat: list[float]) -> dict | None:
    """p50 / p99 / max (ms, one decimal) and n of the click latencies; None without clicks."""
    if not lat:
        return None
    la = np.asarray(lat)
    return {"p50": round(float(np.percentile(la, 50)), 1),
            "p99": round(float(np.percentile(la, 99)), 1),
            "max": round(float(la.max()), 1), "n": len(lat)}


def run(base: str, token: str, sock: str, seconds: float = 10.0, clicks: int = 10,
        budget_s: float = 600.0) -> dict:
    """The console figures against ``rigd web`` at ``base`` (module docstring)."""
    t_start = time.monotonic()
    budget = Budget(budget_s)
    errors: dict[str, str] = {}
    driver, service = make_driver()
    try:
        _get(driver, base + "/")
        budget.wait(lambda: driver.execute_script("return document.readyState") != "loading",
                    "the page")
        driver.execute_script("sessionStorage.setItem('rigd-token', arguments[0])", token)
        _open(driver, base, "", budget)
        settling = _window(driver, service, SETTLE_S)
        page = _window(driver, service, seconds)
        try:
            lat = _clicks(driver, sock, clicks, budget)
        except _step_failures() as exc:      # reported; the other figures still count
            lat, errors["safe_click"] = [], f"{type(exc).__name__}: {exc}"
        if budget.left() < seconds + 60:
            profile = "not run: the bench's time budget is spent"
        else:
            try:
                profile = _profile(driver, seconds)
            except _step_failures() as exc:
                profile = f"not measured: {type(exc).__name__}: {exc}"
        # the same page taking the stream at 50 updates/s (its address asks it, live.js)
        fast, lat50 = None, []
        if budget.left() < seconds + SETTLE_S + 60 + 3 * clicks:
            errors["fast"] = "not run: the bench's time budget is spent"
        else:
            try:
                _open(driver, base, FAST_QUERY, budget)
                _window(driver, service, SETTLE_S)
                fast = _window(driver, service, seconds)
                lat50 = _clicks(driver, sock, clicks, budget)
            except _step_failures() as exc:
                errors["fast"] = f"{type(exc).__name__}: {exc}"
    finally:
        try:
            driver.quit()
        finally:
            service.stop()
    return {
        "console_tab_cpu_percent": page["renderer"],
        "console_tab_cpu_percent_settling": settling["renderer"],
        "console_gpu_process_cpu_percent": page["gpu"],
        "console_browser_process_cpu_percent": page["browser"],
        "console_chromium_cpu_percent": page["sum"],
        "console_tab_where": page["where"],
        "console_tab_profile": profile,
        "console_cpu_seconds": seconds,
        "safe_click_latency_ms": _summary(lat),
        "console_tab_cpu_percent_50hz": fast["renderer"] if fast else None,
        "console_tab_where_50hz": fast["where"] if fast else None,
        "safe_click_latency_ms_50hz": _summary(lat50),
        "console_errors": errors,
        "console_bench_s": round(time.monotonic() - t_start, 1),
        "load_average": [round(x, 2) for x in os.getloadavg()],
    }


def main(seconds: float = 10.0, clicks: int = 10) -> dict:
    """A daemon and ``rigd web`` of their own, then :func:`run`."""
    from bench.web import _start_web

    with tempfile.TemporaryDirectory(prefix="rigd-console-bench-") as d:
        tmp = Path(d)
        daemon, sock = start_daemon(tmp, wait_s=300.0)   # a busy machine: minutes to start
        web = None
        try:
            web, base = _start_web(tmp, sock, wait_s=300.0)
            token = (tmp / "token").read_text().strip()
            return run(base, token, sock, seconds, clicks)
        finally:
            if web is not None:
                web.terminate()
                web.wait(30)
                web.err.close()
            stop_daemon(daemon)


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps(main(), indent=2))
    os._exit(0)
