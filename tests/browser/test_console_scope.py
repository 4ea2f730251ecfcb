"""The console as a scope (issue 22), in headless Chromium on a real ``rigd web`` and daemon:
live plots that stay true across a daemon restart, the fault banner and its reset, the stale
state, the operating-point form, the scope's habits (autoscaled orbit, pause, trigger, cursor,
log cycle times, trends, one axis per unit) and a SAFE click with the Live tab drawing.

Every wait is on a condition in the page or the daemon (no sleeps, no timed asserts).
``RIGD_DOC_SCREENSHOTS=1`` also writes the screenshots docs/web.md shows to docs/img/.
"""

import json
import os
import re
import shutil

import pytest
from selenium.common.exceptions import TimeoutException
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select, WebDriverWait
from testpaths import ROOT
from webproc import WebProcess, config_folder, start_daemon, wait_for


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """``{"d": daemon, "web": rigd web, "tmp": folder}``; a test may replace ``d``."""
    tmp = tmp_path_factory.mktemp("scoperig")
    state = {"d": start_daemon(tmp), "tmp": tmp}
    try:
        state["web"] = WebProcess(tmp, state["d"].sock, tmp / "runs", config_folder(tmp))
        try:
            yield state
        finally:
            state["web"].stop()
    finally:
        state["d"].stop()


def _restart_daemon(rig):
    """A new daemon on the rig's socket (the old one stopped): ``rig["d"]`` is the new one."""
    if rig["d"].proc.poll() is None:
        rig["d"].stop()
    rig["d"].notify.close()                   # its readiness socket: the new one binds it
    (rig["tmp"] / "notify.sock").unlink(missing_ok=True)
    rig["d"] = start_daemon(rig["tmp"])       # the same socket, a new process
    return rig["d"]


@pytest.fixture(autouse=True)
def _daemon_running(request):
    """Before each test: a daemon that a failed test left stopped is started again (one
    failure stays one failure, not the cause of every later test's)."""
    if "rig" in request.fixturenames:
        rig = request.getfixturevalue("rig")
        if rig["d"].proc.poll() is not None:
            _restart_daemon(rig)
    yield


def _wait(browser, cond, timeout=90, what=""):
    return WebDriverWait(browser.driver, timeout, poll_frequency=0.1).until(
        lambda drv: cond(drv), message=what)


def _js(browser, expr):
    return browser.execute_script("return " + expr)


def _open(browser, web, query=""):
    # the page's modules run (the token button wired) after the HTML: on a busy machine the
    # box is there seconds before
    browser.load(web.url + "/" + query, "!!window.rigd", what="the console page's scripts")
    box = browser.find_element(By.ID, "token")
    box.clear()
    box.send_keys(web.token)
    browser.find_element(By.ID, "token-save").click()
    _wait(browser, lambda drv: _js(browser, "window.rigd.mode") == "stream"
          and _js(browser, "window.rigd.daemon !== null"), what="live stream and daemon identity")


def _text(browser, id_):
    return browser.find_element(By.ID, id_).text


_PLOTS_FIT = ("return [...document.querySelectorAll('.js-plotly-plot')].filter("
              "e => e.offsetParent !== null).every("
              "e => e._fullLayout && Math.abs(e._fullLayout.width"
              " - e.getBoundingClientRect().width) < 2)")


def _shot(browser, screenshot, name):
    """The viewport to test-artifacts/; with RIGD_DOC_SCREENSHOTS the whole page (the window
    made as tall as the page, the plots re-fitted) to docs/img/ too."""
    doc = os.environ.get("RIGD_DOC_SCREENSHOTS")
    size = browser.get_window_size()
    if doc:
        chrome = size["height"] - _js(browser, "window.innerHeight")
        browser.set_window_size(size["width"],
                                _js(browser, "document.documentElement.scrollHeight") + chrome)
        _wait(browser, lambda drv: drv.execute_script(_PLOTS_FIT), what="plots fitted")
    for attempt in range(3):     # a renderer too starved to paint in 10 s: try again
        try:
            path = screenshot(name)
            break
        except TimeoutException:
            if attempt == 2:
                raise
    if doc:
        shutil.copyfile(path, ROOT / "docs" / "img" / f"{name}.png")
        browser.set_window_size(size["width"], size["height"])


def _record_axes(browser):
    """{axis title: channels shown on it} of the record view; asserts that every y axis has a
    shown channel (no empty panel), one unit each (its title ends with it), and that no two
    axis titles overlap on the page."""
    got = json.loads(_js(browser, """JSON.stringify((() => {
        const el = document.getElementById('record-plot'), out = {};
        for (const [k, ax] of Object.entries(el.layout)) {
          if (!/^yaxis\\d*$/.test(k)) continue;
          const ref = k === 'yaxis' ? 'y' : 'y' + k.slice(5);
          out[(ax.title || {}).text] = el.data.filter(t => t.visible === true && t.yaxis === ref)
            .map(t => [t.meta, t.name]);
        }
        return out; })())"""))
    for title, chans in got.items():
        assert chans, f"record axis {title!r} has no shown channel: {got}"
        for _, name in chans:
            assert title.endswith(name.split("[", 1)[1].split("]")[0]), (title, name)
    _no_overlapping_titles(browser, "record-plot")
    return {title: {c for c, _ in chans} for title, chans in got.items()}


def _no_overlapping_titles(browser, plot):
    """No two of the plot's titles (axes, plot) and its legend overlap on the page."""
    boxes = json.loads(_js(browser, f"JSON.stringify([...document.querySelectorAll("
                                    f"'#{plot} .infolayer g[class$=\"title\"] text, "
                                    f"#{plot} .legend .bg')]"
                                    ".filter(e => e.getBoundingClientRect().width > 0)"
                                    ".map(e => {const r = e.getBoundingClientRect(); return "
                                    "[e.textContent || 'legend', r.left, r.top, r.right, "
                                    "r.bottom];}))"))
    assert boxes, f"{plot}: no titles found"
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            apart = a[3] <= b[1] or b[3] <= a[1] or a[4] <= b[2] or b[4] <= a[2]
            assert apart, f"{plot}: axis titles overlap: {a} {b}"


def _legend_click(browser, name):
    item = [e for e in browser.find_elements(By.CSS_SELECTOR, "#record-plot .legend .traces")
            if e.find_element(By.CSS_SELECTOR, ".legendtext").text == name]
    assert item, f"{name} not in the legend"
    ActionChains(browser.driver).move_to_element(
        item[0].find_element(By.CSS_SELECTOR, ".legendtext")).click().perform()


def _clear_fault(d):
    if d.ctl_json("status")["fault"]["code"]:
        d.ctl("reset")


def test_restart_under_an_open_page_starts_the_traces_over(browser, screenshot, rig):
    d, web = rig["d"], rig["web"]
    _open(browser, web)
    old_pid = d.ctl_json("ping")["pid"]
    _wait(browser, lambda drv: _js(browser, "window.rigd.daemon.pid") == old_pid
          and _js(browser, "((document.getElementById('traces').data || [{}])[0].meta || {})"
                  ".daemon") == old_pid, what="traces carry the daemon's pid")
    assert f"pid {old_pid}" in _text(browser, "traces-cap")
    _wait(browser, lambda drv: _js(browser, "window.rigd.lastT") > 1.0, what="1 s of loop time")
    old_t = _js(browser, "window.rigd.lastT")
    d.stop()
    # the daemon is gone: the header greys and says since when its values are stale
    _wait(browser, lambda drv: _js(browser, "document.body.classList.contains('stale')"),
          what="stale state")
    stale = _text(browser, "stale-text")
    assert stale.startswith("disconnected — values are stale (last at ")
    # from now on every fetch of the page is logged: while the daemon is down it polls only
    # what the stale state needs (the status: the reason, the way back)
    browser.execute_script("""
        const r = window.rigd, f = window.fetch; r.fetchLog = [];
        window.fetch = function (url, opts) {
          r.fetchLog.push([String(url), performance.now()]);
          return f.apply(this, arguments);
        };""")
    # greyed: the header's values dimmed, the plots too
    assert float(_js(browser, "getComputedStyle(document.querySelector('header#top .item'))"
                              ".opacity")) < 1
    assert float(_js(browser, "getComputedStyle(document.querySelector('.plots figure'))"
                              ".opacity")) < 1
    # the header's stream state stays short (the reason is in its tooltip and the banner)
    assert _text(browser, "stream-state") == "no live stream: polling status, traces stopped"
    # the banner is one line whatever its reason (the whole text in its tooltip): a reason
    # that wrapped it moved the controls below while a click was aiming at one
    moved = _js(browser, """(() => {
        const top = () => document.getElementById('enable').getBoundingClientRect().top;
        const s = document.getElementById('stale-text'), before = top(), old = s.textContent;
        s.textContent = old + ' ' + 'a long reason '.repeat(60);
        const after = top();
        s.textContent = old;
        return after - before; })()""")
    assert moved == 0, f"a longer stale reason moved the controls by {moved} px"
    assert _js(browser, "document.getElementById('stale-text').title").startswith(
        "disconnected — values are stale (last at ")
    # SAFE while the daemon is down: it failed, and the page says so (503, an error) ...
    browser.find_element(By.ID, "safe").click()
    _wait(browser, lambda drv: _text(browser, "message").startswith("safe: ")
          and "(HTTP 503)" in _text(browser, "message"), what="failed SAFE shown")
    assert "error" in browser.find_element(By.ID, "message").get_attribute("class")
    # ... and another command's 503: each goes once the daemon answers again
    browser.find_element(By.ID, "enable").click()
    _wait(browser, lambda drv: _text(browser, "message").startswith("enable: ")
          and "(HTTP 503)" in _text(browser, "message"), what="503 shown")
    _shot(browser, screenshot, "console-stale")
    browser.find_element(By.ID, "safe").click()       # the failed SAFE is the last message
    _wait(browser, lambda drv: _text(browser, "message").startswith("safe: "),
          what="failed SAFE shown again")
    # over more than 6 s down (the histogram's period is 5 s, the experiment's 2 s): the status
    # polled, never the timing nor the experiment (each a 503 in the console before)
    polled = ("(() => { const s = window.rigd.fetchLog.filter(e => e[0] === '/api/status');"
              " return s.length > 1 && s[s.length - 1][1] - s[0][1] > 6000; })()")
    _wait(browser, lambda drv: _js(browser, polled), what="6 s of status polls while down")
    down = {u for u, _ in json.loads(_js(browser, "JSON.stringify(window.rigd.fetchLog)"))}
    assert not {u for u in down if u.startswith(("/api/timing", "/api/experiment"))}, down
    d = _restart_daemon(rig)
    new_pid = d.ctl_json("ping")["pid"]
    assert new_pid != old_pid
    _wait(browser, lambda drv: _js(browser, "window.rigd.daemon && window.rigd.daemon.pid")
          == new_pid, what="the page names the new daemon")
    _wait(browser, lambda drv: not _js(browser, "document.body.classList.contains('stale')")
          and not drv.find_element(By.ID, "stale-banner").is_displayed(),
          what="stale state cleared")
    # the traces were started over: only the new daemon's points, its loop time from ~0
    _wait(browser, lambda drv: (_js(browser, "(document.getElementById('traces').data[0].meta"
                                             " || {}).daemon") == new_pid),
          what="traces redrawn for the new daemon")
    _wait(browser, lambda drv: _text(browser, "message") == "", what="failed SAFE message gone")
    assert "error" not in browser.find_element(By.ID, "message").get_attribute("class")
    assert _js(browser, "window.rigd.restarts.length") >= 1
    assert "restarted" in _text(browser, "live-note")
    # the daemon back: the timing and the experiment are read again
    for path in ("/api/timing", "/api/experiment"):
        _wait(browser, lambda drv, path=path: _js(
            browser, f"window.rigd.fetchLog.some(e => e[0] === '{path}')"), what=f"{path} again")
    buf_t0 = _js(browser, "window.rigd.buf.t[0]")
    assert buf_t0 is not None and buf_t0 < old_t
    # nothing recursed or threw: the only console errors are the failed loads while it was down
    errors = browser.take_console_errors()
    assert all("Failed to load resource" in e or "EventSource" in e or "503" in e
               for e in errors), errors


# two updates handed to the page's own stream handler (live.js push) in one task, the stream's
# real updates cannot interleave: one 100 s of loop time after the newest bucket (a gap), then
# one saying the daemon dropped 3 frames; what the page keeps and says after each
_GAP_PROBE = """
const done = arguments[arguments.length - 1];
import('/static/live.js').then((m) => {
  const r = window.rigd, out = [], t = r.lastT;
  const seen = () => ({restarts: r.restarts.length, epoch: r.epoch, buf: r.buf.t.slice(),
    note: document.getElementById('live-note').textContent});
  out.push(seen());
  m.push({t: [t + 100.0, t + 100.002], min: {e_x: [0, 0]}, max: {e_x: [0.1, 0.1]}, dropped: 0});
  out.push(seen());
  m.push({t: [t + 100.004], min: {e_x: [0]}, max: {e_x: [0.1]}, dropped: 3});
  out.push(seen());
  done({t, out});
}, (e) => done(String(e)));
"""


def test_a_gap_in_the_stream_starts_the_traces_over_visibly(browser, rig):
    d, web = rig["d"], rig["web"]
    _clear_fault(d)
    _open(browser, web)
    _wait(browser, lambda drv: _js(browser, "window.rigd.renders") > 1
          and len(_js(browser, "window.rigd.buf.t")) > 2, what="traces drawn")
    got = browser.execute_async_script(_GAP_PROBE)
    assert isinstance(got, dict), got
    before, gap, dropped = got["out"]
    t = got["t"]
    # a jump of 100 s of loop time: the old points are dropped, never joined to the new ones,
    # and the note above the plots says why
    assert gap["restarts"] == before["restarts"] + 1 and gap["epoch"] == before["epoch"] + 1
    assert gap["buf"] == pytest.approx([t + 100.0, t + 100.002])
    assert re.fullmatch(r"traces restarted at \S+: gap in the stream from [\d.]+ s to [\d.]+ s",
                        gap["note"]), gap["note"]
    # frames the daemon dropped: a gap too, however small the step of loop time
    assert dropped["restarts"] == gap["restarts"] + 1
    assert dropped["buf"] == pytest.approx([t + 100.004])
    assert dropped["note"].endswith("(3 frames dropped)"), dropped["note"]
    # the real stream goes on behind the made-up updates (its loop time "went back" from
    # them): the page starts over once more, draws the daemon's traces of the new epoch and
    # nothing threw
    _wait(browser, lambda drv: _js(browser, "window.rigd.epoch") > dropped["epoch"]
          and _js(browser, "window.rigd.lastT") < t + 100.0, what="the real stream again")
    _wait(browser, lambda drv: _js(browser, "(document.getElementById('traces').data[0].meta"
                                   " || {}).epoch === window.rigd.epoch && document"
                                   ".getElementById('traces').data[0].x.length >= 2"),
          what="traces of the new epoch drawn")
    assert browser.console_errors() == []


def test_fault_banner_with_reset_and_a_refusal_that_clears_with_the_fault(browser, screenshot,
                                                                         rig):
    d, web = rig["d"], rig["web"]
    _clear_fault(d)
    _open(browser, web)
    _wait(browser, lambda drv: _js(browser, "window.rigd.renders") > 0, what="traces drawn")
    assert not browser.find_element(By.ID, "fault-banner").is_displayed()
    # SAFE goes out within the press's own event dispatch: before any drawing the page has
    # queued (draws run in later animation-frame tasks). The page's fetch of /api/safe is
    # recorded with whether the pointerdown was still being dispatched and the draw count.
    browser.execute_script("""
        const r = window.rigd; r.probe = {down: false, sent: null, n: 0};
        window.addEventListener('pointerdown', () => { r.probe.down = true;
          r.probe.rendersAtDown = r.renders + r.orbitRenders; }, true);
        window.addEventListener('pointerdown', () => { r.probe.down = false; }, false);
        const f = window.fetch;
        window.fetch = function (url, opts) {
          if (String(url).endsWith('/api/safe')) r.probe.n += 1;
          if (String(url).endsWith('/api/safe') && !r.probe.sent)
            r.probe.sent = {inDown: r.probe.down, renders: r.renders + r.orbitRenders};
          return f.apply(this, arguments);
        };""")
    browser.find_element(By.ID, "safe").click()       # with the Live tab drawing
    probe = _wait(browser, lambda drv: _js(browser, "window.rigd.probe.sent"), what="SAFE sent")
    assert probe["inDown"] is True, probe
    assert probe["renders"] == _js(browser, "window.rigd.probe.rendersAtDown"), probe
    wait_for(lambda: d.ctl_json("status")["fault"]["name"] == "operator_safe", timeout=60,
             what="operator_safe latched")
    banner = _wait(browser, lambda drv: drv.find_element(By.ID, "fault-banner").is_displayed()
                   and drv.find_element(By.ID, "fault-banner"), what="fault banner")
    assert "FAULT operator_safe latched at cycle" in banner.text
    # enable is refused with the fault's text; that message goes once the fault is reset
    browser.find_element(By.ID, "enable").click()
    _wait(browser, lambda drv: "(HTTP 409)" in _text(browser, "message"), what="409 shown")
    assert "operator_safe" in _text(browser, "message")
    _shot(browser, screenshot, "console-fault")
    browser.find_element(By.ID, "banner-reset").click()
    wait_for(lambda: d.ctl_json("status")["fault"]["code"] == 0, timeout=60, what="reset")
    _wait(browser, lambda drv: not drv.find_element(By.ID, "fault-banner").is_displayed(),
          what="banner gone")
    _wait(browser, lambda drv: "409" not in _text(browser, "message"), what="409 message gone")
    # one press, one request: the click after the pointerdown is the same press
    assert _js(browser, "window.rigd.probe.n") == 1
    # the keyboard's press (Enter on the focused button: a click without a pointerdown) sends
    # it too, once — and at once after the last: no time window swallows a second press
    browser.find_element(By.ID, "safe").send_keys(Keys.ENTER)
    wait_for(lambda: d.ctl_json("status")["fault"]["name"] == "operator_safe", timeout=60,
             what="operator_safe latched by the keyboard's press")
    _wait(browser, lambda drv: _js(browser, "window.rigd.probe.n") == 2, what="second request")
    d.ctl("reset")
    _wait(browser, lambda drv: not drv.find_element(By.ID, "fault-banner").is_displayed(),
          what="banner gone after the keyboard's SAFE")
    assert _js(browser, "window.rigd.probe.n") == 2
    # the SAFE click's latency, measured the bench's way (not asserted: timing is the bench's)
    click = _js(browser, "window.rigd.safeClicks[0]")
    assert click["seq"] is not None and click["wall_ms"] > 0
    errors = browser.take_console_errors()              # the 409 response
    assert all("409" in e for e in errors), errors


def test_lines_on_the_page_canvas_and_server_side_decimation(browser, rig):
    d, web = rig["d"], rig["web"]
    _clear_fault(d)
    _open(browser, web)
    _wait(browser, lambda drv: _js(browser, "window.rigd.renders") > 1
          and _js(browser, "window.rigd.orbitRenders") > 1, what="traces and orbit drawn")
    # under a policy that runs no string as code (no 'unsafe-eval': Plotly's SVG figures need
    # none); a violation would be a console error, and the browser fixture fails on those
    csp = browser.driver.execute_async_script(
        "fetch('/').then(r => arguments[0](r.headers.get('content-security-policy')))")
    assert "script-src 'self';" in csp and "unsafe-eval" not in csp, csp
    # every live plot's lines and bars are the page's own canvas strokes over Plotly's frame
    # (canvas.js): the figures' traces are SVG scatter (bar: the cycle times) with their SVG
    # lines and bars hidden, the canvas has them
    _wait(browser, lambda drv: _js(browser, "window.rigd.trendRenders > 0 && "
                                   "window.rigd.timingRenders > 0 && window.rigd.histRenders > 0"),
          what="trends and cycle times drawn")
    for key, kind in (("orbit", "scatter"), ("traces", "scatter"), ("trends", "scatter"),
                      ("timing", "bar"), ("timing-hist", "bar")):
        types = _js(browser, f"document.getElementById('{key}').data.map(t => t.type)")
        assert set(types) == {kind}, (key, types)
        layer = "scatterlayer" if kind == "scatter" else "barlayer"
        assert _js(browser, f"getComputedStyle(document.querySelector('#{key} .{layer}'))"
                            ".display") == "none"
        # Plotly was given no points to lay its frame out around (it computes paths even
        # where they are hidden): its own copy of each trace holds one null point
        assert _js(browser, f"document.getElementById('{key}')._fullData.every("
                            "t => (t.x || []).length <= 1)"), key
        # pixels drawn on the overlay, inside the figure's plot area
        inked = (f"(() => {{ const c = document.querySelector('#{key} canvas.lines-overlay');"
                 " if (!c) return 0; const p = c.getContext('2d').getImageData(0, 0, c.width,"
                 " c.height).data; let n = 0; for (let i = 3; i < p.length; i += 4) n += p[i] > 0;"
                 " return n; })()")
        _wait(browser, lambda drv, inked=inked: _js(browser, inked) > 50, what=f"{key} lines drawn")
    # the stream is decimated by the server: 20 min/max buckets per update at 10 updates/s,
    # each bucket covering many 5 kHz frames (the page never receives the raw frames)
    sub = _js(browser, "window.rigd.subscription")
    assert sub["points"] == 20 and sub["rate_hz"] == 10, sub
    u0 = _js(browser, "window.rigd.updates")
    _wait(browser, lambda drv: _js(browser, "window.rigd.updates") > u0 + 20, what="20 updates")
    assert 1 <= _js(browser, "window.rigd.maxBuckets") <= 20
    t = _wait(browser, lambda drv: (lambda v: v if len(v) >= 10 else None)(
        _js(browser, "window.rigd.buf.t")), what="10 buckets in the buffer")
    # the page keeps the buckets of the last 2.5 s of loop time (live.js KEEP_S), however the
    # updates were spread over the wall clock: on a busy host the loop lags and more updates
    # fall into those 2.5 s, so the count of buckets is not bounded by the nominal 200/s
    assert 0 < t[-1] - t[0] <= 2.5, (t[0], t[-1])
    assert all(b > a for a, b in zip(t, t[1:]))        # in loop-time order, none twice
    # decimated: a bucket holds several 5 kHz frames on average (one each would be raw frames;
    # 25 each at the nominal rate, fewer only as far as the loop lags the wall clock)
    assert (t[-1] - t[0]) / (len(t) - 1) >= 2 / 5000, len(t)
    # another subscription asked in the page's address (bench/console.py's 50 updates/s); a
    # value out of range or not a number is the default, never sent to the server as is
    for query, want in (("?rate_hz=50&points=4", (50, 4)), ("?rate_hz=500&points=x", (10, 20))):
        _open(browser, web, query)
        sub = _js(browser, "window.rigd.subscription")
        assert (sub["rate_hz"], sub["points"]) == want, (query, sub)
    assert browser.console_errors() == []


# the page's own drawing of the cycle-time percentiles (slowplots.js drawTiming) for given
# values, run synchronously in one task (the stream's updates cannot interleave): the frame
# laid out (Plotly) or not, the log axis' range, and the canvas' alpha just below and just above
# the top of the compute 'max' bar (x = 3, offset -0.4, width 0.4) at the pixel Plotly's own
# axis gives for the value
_TIMING_PROBE = """
const [done, values] = [arguments[arguments.length - 1], arguments[0]];
import('/static/slowplots.js').then((m) => {
  const r = window.rigd, el = document.getElementById('timing'), out = [], keep = r.timing;
  for (const v of values) {
    r.timing = v;
    const n0 = (r.frameLayouts || {}).timing || 0;
    m.drawTiming();
    const fl = el._fullLayout, xa = fl.xaxis, ya = fl.yaxis, cv = el.rigdCanvas;
    const dpr = cv.width / fl.width, top = ya._offset + ya.l2p(Math.log10(v.compute_us.max));
    const cx = xa._offset + xa.l2p(2.8), ctx = cv.getContext('2d');
    const alpha = (y) => ctx.getImageData(Math.round(cx * dpr), Math.round(y * dpr), 1, 1)
      .data[3];
    out.push({laid: (r.frameLayouts.timing || 0) - n0, range: ya.range.slice(),
              below: alpha(top + 3), above: alpha(top - 3), type: ya.type,
              cap: document.getElementById('timing-cap').textContent});
  }
  r.timing = keep;
  done(out);
}, (e) => done(String(e)));
"""


def _pct(p50, p99, p999, mx):
    return {"p50": p50, "p99": p99, "p999": p999, "max": mx}


def test_cycle_times_are_canvas_bars_on_log_axes(browser, rig):
    d, web = rig["d"], rig["web"]
    _clear_fault(d)
    _open(browser, web)
    _wait(browser, lambda drv: _js(browser, "window.rigd.timingRenders > 0 && "
                                   "window.rigd.histRenders > 0"), what="cycle times drawn")
    late = _pct(1.0, 5.0, 30.0, 500.0)
    got = browser.execute_async_script(_TIMING_PROBE, [
        {"compute_us": _pct(10.0, 20.0, 50.0, 200.0), "lateness_us": late},
        # new values within the same decades: the bars move, the frame stays
        {"compute_us": _pct(12.0, 25.0, 60.0, 300.0), "lateness_us": late},
        # a maximum beyond the top decade: the axis re-ranges (one frame laid out)
        {"compute_us": _pct(12.0, 25.0, 60.0, 5000.0), "lateness_us": late},
    ])
    assert isinstance(got, list), got
    first, same, wider = got
    assert first["type"] == "log"
    assert first["range"][0] <= 0 and first["range"][1] >= 3           # 0.1 … 500 µs inside
    assert same["laid"] == 0 and same["range"] == first["range"], got
    assert wider["laid"] == 1 and wider["range"][1] >= 3.7, got         # log10(5000) = 3.7
    # the bar drawn up to its value on the log axis, nothing above it
    for g in got:
        assert g["below"] > 0 and g["above"] == 0, got
    # the values themselves in the caption (3 significant digits), the misses with them
    assert "compute p50 12 / p99 25 / p99.9 60 / max 5000 µs" in wider["cap"], wider["cap"]
    assert "lateness p50 1 / p99 5 / p99.9 30 / max 500 µs" in wider["cap"]
    assert "misses " in wider["cap"]
    # the histogram: the daemon's bars, on the canvas, each series' cycles counted in the
    # caption (the samples beyond the last bar too, when there are)
    cap = _wait(browser, lambda drv: _text(browser, "timing-hist-cap"), what="histogram caption")
    assert re.fullmatch(r"compute: \d+ cycles in bars of [\d.]+ µs(, \d+ beyond them)? · "
                        r"lateness: \d+ cycles in bars of [\d.]+ µs(, \d+ beyond them)?", cap), cap
    assert _js(browser, "document.getElementById('timing-hist').layout.yaxis.type") == "log"
    assert browser.console_errors() == []


def test_operating_point_form_follows_refuses_and_confirms(browser, screenshot, rig):
    d, web = rig["d"], rig["web"]
    _clear_fault(d)
    _open(browser, web)
    omega, pinj = browser.find_element(By.ID, "op-omega"), browser.find_element(By.ID, "op-pinj")
    # the fields show the daemon's set-point (status.set_point), whatever it is now ...
    sp = d.ctl_json("status")["set_point"]
    _wait(browser, lambda drv: omega.get_attribute("value") == f"{sp['omega_rpm']:.0f}"
          and pinj.get_attribute("value") == f"{sp['p_inj_bar']:.2f}",
          what="fields show the daemon's set-point")
    assert _text(browser, "op-now").startswith(
        f"set-point {sp['omega_rpm']:.0f} rpm / {sp['p_inj_bar']:.2f} bar")
    # ... and follow it when someone else changes it (rigd ctl op while the page is open)
    d.ctl("op", "2000", "5")
    assert d.ctl_json("status")["set_point"] == {"omega_rpm": 2000.0, "p_inj_bar": 5.0,
                                                 "source": "op"}
    _wait(browser, lambda drv: omega.get_attribute("value") == "2000"
          and pinj.get_attribute("value") == "5.00", what="fields follow the set-point")
    _wait(browser, lambda drv: _text(browser, "op-now").startswith(
        "set-point 2000 rpm / 5.00 bar · measured "), what="set-point and measured shown")
    # an empty field: refused in the page, nothing sent
    omega.clear()
    browser.find_element(By.ID, "op-set").click()
    _wait(browser, lambda drv: "nothing sent" in _text(browser, "message"), what="refused")
    assert _text(browser, "message").startswith("op: Ω: a number in rpm is required, got an empty")
    assert "invalid" in omega.get_attribute("class")
    omega.send_keys("fast")
    browser.find_element(By.ID, "op-set").click()
    _wait(browser, lambda drv: "got 'fast'" in _text(browser, "message"), what="refused")
    # the server refuses the same (a page that skipped its check)
    status = browser.execute_async_script(
        "const done = arguments[0];"
        "fetch('/api/op', {method: 'POST', headers: {'Content-Type': 'application/json',"
        " 'Authorization': 'Bearer ' + sessionStorage.getItem('rigd-token')},"
        " body: JSON.stringify({omega_rpm: '', p_inj_bar: 5})}).then(r => done(r.status));")
    assert status == 400
    assert d.ctl_json("status")["last_frame"]["omega_rpm"] == pytest.approx(2000, abs=1)
    omega.clear()
    omega.send_keys("1500")
    browser.find_element(By.ID, "op-set").click()
    _wait(browser, lambda drv: "applied Ω = 1500 rpm, P_I = 5.00 bar" in _text(browser, "message"),
          what="confirmed with the applied value")
    # confirmed only once applied: the daemon's set-point is the new one already
    assert d.ctl_json("status")["set_point"]["omega_rpm"] == 1500.0
    assert "edited" not in omega.get_attribute("class")        # following the set-point again
    _wait(browser, lambda drv: _text(browser, "op-now").startswith("set-point 1500 rpm / 5.00 bar")
          and omega.get_attribute("value") == "1500", what="the page's set-point 1500")
    wait_for(lambda: abs(d.ctl_json("status")["last_frame"]["omega_rpm"] - 1500) < 1, timeout=60,
             what="daemon at 1500 rpm")
    _wait(browser, lambda drv: "measured 1500 rpm" in _text(browser, "op-now"),
          what="measured 1500")
    _shot(browser, screenshot, "console-op")
    errors = browser.take_console_errors()              # the 400 of the raw fetch
    assert all("400" in e for e in errors), errors


def test_scope_orbit_pause_trigger_cursor_trends_units(browser, screenshot, rig):
    d, web = rig["d"], rig["web"]
    _clear_fault(d)
    _open(browser, web)
    _wait(browser, lambda drv: _js(browser, "window.rigd.orbitRenders") > 2
          and _js(browser, "window.rigd.renders") > 1, what="orbit and traces drawn")
    gap = _js(browser, "window.rigd.filmGap")
    # autoscaled orbit: the view fits the orbit (the film gap circle is context, not the scale)
    orbit = json.loads(_js(browser, "JSON.stringify(document.getElementById('orbit').data[0])"))
    r = _js(browser, "document.getElementById('orbit').layout.xaxis.range[1]")
    m = max(max(abs(v) for v in orbit["x"]), max(abs(v) for v in orbit["y"]))
    assert m <= r <= max(6 * m, 0.05) or m > gap / 2
    assert "film gap" in _js(browser, "document.getElementById('orbit').layout.annotations[0].text")
    browser.find_element(By.CSS_SELECTOR, "[data-orbit=gap]").click()
    _wait(browser, lambda drv: _js(browser, "document.getElementById('orbit').layout.xaxis"
                                   ".range[1]") >= gap, what="film-gap scale")
    browser.find_element(By.CSS_SELECTOR, "[data-orbit=auto]").click()
    _wait(browser, lambda drv: "scale auto" in _text(browser, "orbit-cap"), what="auto scale")
    # zoom: a drag on the orbit narrows the view and the redraws keep it (scale "user") ...
    r_auto = _js(browser, "document.getElementById('orbit').layout.xaxis.range[1]")
    drag = browser.find_element(By.CSS_SELECTOR, "#orbit .nsewdrag")
    ActionChains(browser.driver).move_to_element_with_offset(drag, -40, -40).click_and_hold() \
        .move_by_offset(40, 40).move_by_offset(40, 40).release().perform()
    _wait(browser, lambda drv: "scale user" in _text(browser, "orbit-cap"), what="zoomed")
    zoomed = _js(browser, "document.getElementById('orbit').layout.xaxis.range")
    assert zoomed[1] - zoomed[0] < 2 * r_auto
    n0 = _js(browser, "window.rigd.orbitRenders")
    try:
        _wait(browser, lambda drv: _js(browser, "window.rigd.orbitRenders") > n0 + 3,
              timeout=180, what="redraws")
    except TimeoutException:
        raise AssertionError("no orbit redraws after the zoom: " + _js(
            browser, "JSON.stringify([window.rigd.orbitRenders, window.rigd.renders, "
            "window.rigd.updates, window.rigd.mode, window.rigd.stale, window.rigd.orbitScale])"
        )) from None
    assert _js(browser, "document.getElementById('orbit').layout.xaxis.range") == zoomed
    # ... and a double-click goes back to auto
    ActionChains(browser.driver).double_click(drag).perform()
    _wait(browser, lambda drv: "scale auto" in _text(browser, "orbit-cap"), what="auto again")
    # units on every axis, one axis group per unit, distinct colours
    lay = json.loads(_js(browser, "JSON.stringify(document.getElementById('traces').layout)"))
    titles = [lay[k]["title"]["text"] for k in ("yaxis", "yaxis2", "yaxis3")]
    assert titles == ["e, µm", "x/y, V", "valves, V"]
    # which channel on which axis: the lumped x/y signals and the valves on V axes of their own
    on = json.loads(_js(browser, "JSON.stringify(document.getElementById('traces').data"
                                 ".map(t => [t.name, t.yaxis]))"))
    assert {n for n, a in on if a == "y"} == {"e_x", "e_y"}
    assert {n for n, a in on if a == "y2"} == {"u_x", "u_y", "r_x", "r_y", "K∞ k_x", "K∞ k_y"}
    assert {n for n, a in on if a == "y3"} == {f"{k}_p{i}" for k in "yr" for i in range(1, 5)}
    # distinct over each whole plot (one legend for all its axes)
    for key in ("traces", "trends"):
        cols = [c for c in _js(browser, f"document.getElementById('{key}').data"
                                        ".map(t => t.line && t.line.color)") if c]
        assert len(cols) == len(set(cols)), (key, cols)
    # cycle times on a log scale
    _wait(browser, lambda drv: _js(browser, "(document.getElementById('timing').layout || {})"
                                   ".yaxis") is not None, what="timing drawn")
    assert _js(browser, "document.getElementById('timing').layout.yaxis.type") == "log"
    # pause freezes the traces while the stream goes on; resume follows it again
    browser.find_element(By.ID, "pause").click()
    _wait(browser, lambda drv: "PAUSED" in _text(browser, "traces-cap"), what="paused")
    frozen = _js(browser, "document.getElementById('traces').data[0].meta.t0")
    u0 = _js(browser, "window.rigd.updates")
    _wait(browser, lambda drv: _js(browser, "window.rigd.updates") > u0 + 20, what="stream goes on")
    assert _js(browser, "document.getElementById('traces').data[0].meta.t0") == frozen
    # the cursor readout: loop time and every channel with its unit at the mouse
    plot = browser.find_element(By.CSS_SELECTOR, "#traces .nsewdrag")
    ActionChains(browser.driver).move_to_element(plot).perform()
    _wait(browser, lambda drv: _text(browser, "cursor").startswith("cursor: loop t "),
          what="cursor readout")
    assert " µm" in _text(browser, "cursor") and " V" in _text(browser, "cursor")
    browser.find_element(By.ID, "pause").click()
    _wait(browser, lambda drv: (_js(browser, "document.getElementById('traces').data[0].meta.t0")
                                or 0) > frozen, what="live again")
    # trigger on a level: e_x rising through its median freezes the traces centred on the
    # bucket where its maximum crossed the level
    Select(browser.find_element(By.ID, "trig-mode")).select_by_value("level")
    Select(browser.find_element(By.ID, "trig-chan")).select_by_value("e_x")
    Select(browser.find_element(By.ID, "trig-edge")).select_by_value("rising")
    median = _js(browser, "(() => { const v = window.rigd.buf.e_x.hi.filter(x => x !== null)"
                          ".sort((a, b) => a - b); return v[Math.floor(v.length / 2)]; })()")
    box = browser.find_element(By.ID, "trig-level")
    box.clear()
    box.send_keys(f"{median:.5f}")
    browser.find_element(By.ID, "trig-arm").click()
    _wait(browser, lambda drv: "TRIGGERED" in _text(browser, "scope-state"), what="level trigger")
    assert "e_x rising through" in _text(browser, "scope-state")
    hit = json.loads(_js(browser, "(() => { const v = window.rigd.view.buf, t = window.rigd."
                                  "trigger.t, k = v.t.indexOf(t); return JSON.stringify("
                                  "[k, v.e_x.hi[k - 1], v.e_x.hi[k], window.rigd.trigger"
                                  ".level, v.t[0] - t, v.t[v.t.length - 1] - t]); })()"))
    k, before, at, level, first, last = hit
    assert k > 0 and before < level <= at, hit
    assert first < 0 < last                                # the window is around the trigger
    _wait(browser, lambda drv: _js(browser, "document.getElementById('traces').layout.xaxis"
                                   ".title.text") == "t − t_trigger, s", what="trigger view drawn")
    # trigger on a fault: the traces freeze centred on the latching cycle
    Select(browser.find_element(By.ID, "trig-mode")).select_by_value("fault")
    browser.find_element(By.ID, "trig-arm").click()
    _wait(browser, lambda drv: _text(browser, "scope-state").startswith("armed"), what="armed")
    d.ctl("safe")
    fault_seq = d.ctl_json("status")["fault"]["seq"]
    _wait(browser, lambda drv: "TRIGGERED" in _text(browser, "scope-state"), what="triggered")
    assert _js(browser, "window.rigd.trigger.t") == pytest.approx(fault_seq / 5000.0, abs=1e-3)
    _wait(browser, lambda drv: _js(browser, "document.getElementById('traces').layout.xaxis"
                                   ".range[0]") < 0 < _js(
        browser, "document.getElementById('traces').layout.xaxis.range[1]"),
        what="traces centred on the trigger")
    # the trend shows the fault event, beside Ω, P_I and misses/s on their own axes
    _wait(browser, lambda drv: _js(browser, "document.getElementById('trends').data[3].x"
                                   ".length") >= 1, what="fault on the trend")
    trends = json.loads(_js(browser, "JSON.stringify(document.getElementById('trends').data"
                                     ".map(t => [t.name, t.yaxis, t.y, t.text || null]))"))
    assert [(n, a) for n, a, _, _ in trends] == [("Ω", "y"), ("P_I", "y2"), ("misses/s", "y3"),
                                                 ("fault", "y3")]
    assert "operator_safe" in trends[3][3]
    assert len(trends[0][2]) >= 2
    assert trends[1][2][-1] == pytest.approx(d.ctl_json("status")["last_frame"]["p_inj_bar"],
                                             abs=0.05)
    tl = json.loads(_js(browser, "JSON.stringify(document.getElementById('trends').layout)"))
    assert [tl[k]["title"]["text"] for k in ("yaxis", "yaxis2", "yaxis3")] == \
        ["Ω, rpm", "P_I, bar", "misses/s"]
    # every axis of every live plot is titled (with its unit where it has one); the cycle-time
    # histogram's counts on a log scale too
    _wait(browser, lambda drv: _js(browser, "window.rigd.histRenders") > 0, what="histogram")
    assert _js(browser, "document.getElementById('timing-hist').layout.yaxis.type") == "log"
    for key in ("orbit", "traces", "trends", "timing", "timing-hist"):
        lay = json.loads(_js(browser, f"JSON.stringify(document.getElementById('{key}').layout)"))
        axes = {k: (v.get("title") or {}).get("text") for k, v in lay.items()
                if re.fullmatch(r"[xy]axis\d*", k)}
        assert axes and all(axes.values()), (key, axes)
        _no_overlapping_titles(browser, key)
    _shot(browser, screenshot, "console-scope")
    d.ctl("reset")


def test_record_view_one_axis_per_unit_and_failed_run_reason(browser, screenshot, rig):
    d, web, tmp = rig["d"], rig["web"], rig["tmp"]
    _clear_fault(d)
    # a PRBS long enough to be running whenever SAFE lands, however slow the machine
    long = (tmp / "config" / "experiments" / "prbs.yaml").read_text()
    long = re.sub(r"(?m)^duration_s:.*$", "duration_s: 120.0", long)
    long = re.sub(r"(?m)^name:.*$", "name: web-long", long)
    (tmp / "config" / "experiments" / "web-long.yaml").write_text(long)
    _open(browser, web)
    _wait(browser, lambda drv: len(drv.find_elements(By.CSS_SELECTOR, "#exp-select option")) > 2,
          what="experiments listed")
    Select(browser.find_element(By.ID, "exp-select")).select_by_value(
        "config/experiments/web-long.yaml")
    Select(browser.find_element(By.ID, "trig-mode")).select_by_value("experiment")
    browser.find_element(By.ID, "trig-arm").click()
    _wait(browser, lambda drv: _text(browser, "scope-state") == "armed: an experiment starting",
          what="armed on an experiment")
    browser.find_element(By.ID, "start").click()
    wait_for(lambda: d.ctl_json("experiment").get("state") == "running", timeout=120,
             interval=0.1, what="experiment running")
    # past the settling check: the PRBS is playing (r = excitation while K∞ is off), so the
    # point has a record when SAFE ends it (SAFE during settling leaves no record to open)
    wait_for(lambda: d.ctl_json("status")["last_frame"]["r_x"] != 0.0, timeout=120,
             interval=0.1, what="PRBS playing")
    # the trigger fired on the start (frozen around it)
    _wait(browser, lambda drv: "TRIGGERED" in _text(browser, "scope-state")
          and "experiment started" in _text(browser, "scope-state"), what="experiment trigger")
    browser.find_element(By.ID, "safe").click()           # ends it: failed, the fault named
    wait_for(lambda: d.ctl_json("experiment").get("state") == "failed", timeout=120,
             what="experiment failed")
    browser.find_element(By.ID, "tab-runs").click()
    row = _wait(browser, lambda drv: [r for r in drv.find_elements(
        By.CSS_SELECTOR, "#runs-table tbody tr") if "failed" in r.text
        and r.find_elements(By.CSS_SELECTOR, "button.open-record")], what="failed run listed")[0]
    status = row.find_element(By.CSS_SELECTOR, "td.status").text
    assert status.startswith("failed: ") and "operator_safe" in status    # the API's reason
    row.find_element(By.CSS_SELECTOR, "button.open-record").click()
    _wait(browser, lambda drv: _js(browser, "(document.getElementById('record-plot').data "
                                   "|| []).length") > 0, what="record plotted")
    axes = _record_axes(browser)
    assert axes["µm"] == {"e_x", "e_y"}                                # not the file's "um"
    assert axes["x/y, V"] >= {"u_x", "u_y", "r_x", "r_y"}
    assert "valves, V" not in axes                # no valve shown: no empty valve panel
    colours = _js(browser, "document.getElementById('record-plot').data.map(t => t.line.color)")
    assert len(colours) == len(set(colours))
    # a legend click shows a valve: the valves get their own V axis (not the x/y one) ...
    _legend_click(browser, "y_p1 [V]")
    _wait(browser, lambda drv: "valves, V" in _record_axes(browser), what="valve axis shown")
    axes = _record_axes(browser)
    assert axes["valves, V"] == {"y_p1"} and "y_p1" not in axes["x/y, V"]
    # ... hiding the last channel of a unit takes its panel away (Ω: the rpm axis)
    _legend_click(browser, "omega_rpm [rpm]")
    _wait(browser, lambda drv: "rpm" not in _record_axes(browser), what="rpm axis gone")
    # every shown channel is drawn (a path; a constant one simplified to a few points), the
    # varying positions with their thousands of buckets
    drawn = ("JSON.stringify([document.getElementById('record-plot').data.filter("
             "t => t.visible === true).length, [...document.querySelectorAll("
             "'#record-plot .scatterlayer .js-line')].map(p => (p.getAttribute('d') || '')"
             ".length)])")
    try:
        _wait(browser, lambda drv: (lambda n, d: len([x for x in d if x > 0]) == n
                                    and sum(x > 5000 for x in d) >= 2)(
            *json.loads(_js(browser, drawn))), what="every shown channel drawn")
    except TimeoutException:
        raise AssertionError(f"shown channels vs drawn paths: {_js(browser, drawn)}") from None
    _shot(browser, screenshot, "console-record")
    d.ctl("reset")
    errors = browser.take_console_errors()
    assert errors == [], errors

