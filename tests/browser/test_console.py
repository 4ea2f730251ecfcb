"""The web console in headless Chromium, on a real ``rigd web`` process and a real daemon
(``rigd run``, simulated rig): the page loads without console errors, the live view moves,
the page's controls reach the daemon (with the token only), a bad experiment upload is one
line on the page and leaves the daemon unharmed, a run's record opens. Screenshots go to
test-artifacts/screenshots/ (console.png, K∞ on, is copied to docs/img/console.png)."""

import json

import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select, WebDriverWait
from webproc import daemon_and_web, wait_for

BAD_EXPERIMENT = """kind: prbs
name: bad-upload
operating_point: {omega_rpm: 0, p_inj_bar: 4.0}
amplitude_v: 1.0
duration_s: 4.0
lead_in_s: 0.4
switch_probability: 1.7
"""


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("consolerig")
    with daemon_and_web(tmp) as (d, web):
        yield d, web, tmp


def _wait(browser, cond, timeout=60, what=""):
    return WebDriverWait(browser.driver, timeout, poll_frequency=0.1).until(
        lambda drv: cond(drv), message=what)


def _load(browser, web):
    """The console page loaded and its scripts run (``window.rigd``, set by core.js: its
    buttons wired, main() started); a busy machine's slow load is waited for, bounded."""
    browser.load(web.url + "/", "!!window.rigd", what="the console page's scripts")


def _open(browser, web, token=None):
    """The console page, logged in with ``token`` (default: the control token) typed in its
    token box: every read needs a token (docs/web.md, Security)."""
    _load(browser, web)
    box = browser.find_element(By.ID, "token")
    box.clear()
    box.send_keys(token or web.token)
    browser.find_element(By.ID, "token-save").click()
    _wait(browser, lambda drv: drv.execute_script("return window.rigd.mode") == "stream",
          what="live stream connected")


def _js(browser, expr):
    return browser.execute_script("return " + expr)


def _message(browser):
    m = browser.find_element(By.ID, "message")
    return m.text, m.get_attribute("class")


def test_page_loads_and_live_view_moves(browser, screenshot, rig):
    d, web, _ = rig
    _open(browser, web)
    _wait(browser, lambda drv: _js(browser, "window.rigd.orbitRenders") > 0, what="orbit drawn")
    c0 = int(browser.find_element(By.ID, "cycle").text)
    o0 = _js(browser, "window.rigd.orbitRenders")
    x0 = _js(browser, "document.getElementById('orbit').data[0].x.slice(-5)")
    # 2 s of loop time later (5 kHz): the counter on the page and the orbit have moved
    _wait(browser, lambda drv: int(drv.find_element(By.ID, "cycle").text) >= c0 + 10000,
          what="cycle counter advanced by 2 s")
    _wait(browser, lambda drv: _js(browser, "window.rigd.orbitRenders") >= o0 + 2 and _js(
        browser, "document.getElementById('orbit').data[0].x.slice(-5)") != x0,
        what="orbit redrawn with new points")
    assert _js(browser, "document.getElementById('orbit').layout.shapes[0].x1") == 25.0
    # traces carrying the daemon that drew them
    # (WebGL where the browser has a GPU; SVG where WebGL would run on the CPU, as here)
    assert _js(browser, "document.getElementById('orbit').data[0].type") == _js(
        browser, "window.rigd.traceType")
    pid = d.ctl_json("ping")["pid"]
    _wait(browser, lambda drv: _js(browser, "(document.getElementById('traces').data[0].meta"
                                   " || {}).daemon") == pid, what="daemon pid on the traces")
    # the traces are drawn from the streamed buckets: at least one min/max pair, ending
    # within the 2 s window of the newest frame (how many buckets depends on the machine's
    # load: a starved socket process sends fewer, larger updates)
    _wait(browser, lambda drv: _js(browser, "(document.getElementById('traces').data || [{x: []}])"
                                   "[0].x.length") >= 2, what="displacement trace drawn")
    # x is t - now (s): the last bucket within the 2 s window before the newest frame
    last_x = _js(browser, "document.getElementById('traces').data[0].x.slice(-1)[0]")
    assert -2.0 <= last_x <= 0.0
    assert browser.find_element(By.ID, "safe").is_displayed()
    # the cycle-time histogram: bars of the daemon's own timing histogram (real-time clock)
    _wait(browser, lambda drv: _js(browser, "window.rigd.histRenders") > 0 and _js(
        browser, "document.getElementById('timing-hist').data.length") > 0,
        what="cycle-time histogram drawn")
    counts = _js(browser, "document.getElementById('timing-hist').data[0].y")
    assert sum(counts) > 0 and all(c >= 0 for c in counts)
    ctl_seq = d.ctl_json("status")["seq"]
    assert abs(ctl_seq - int(browser.find_element(By.ID, "cycle").text)) < 5 * 5000
    screenshot("console-live")
    assert browser.console_errors() == []


def test_enable_from_the_page_enables_kinf(browser, screenshot, rig):
    d, web, _ = rig
    d.ctl("disable")
    _open(browser, web, token=web.token)
    browser.find_element(By.ID, "enable").click()
    wait_for(lambda: d.ctl_json("status")["controller"]["enabled"], timeout=30,
             what="rigd ctl status: K∞ enabled")
    _wait(browser, lambda drv: drv.find_element(By.ID, "kinf").text == "on",
          what="page shows K∞ on")
    assert _message(browser)[1].endswith("ok")
    screenshot("console")          # docs/img/console.png (README)
    browser.find_element(By.ID, "disable").click()
    wait_for(lambda: not d.ctl_json("status")["controller"]["requested"], timeout=30,
             what="K∞ disabled")


def _button_words(browser):
    """What the page's messages must say to press: the token button's own label."""
    return f'press "{browser.find_element(By.ID, "token-save").text.strip()}"'


def test_page_without_a_token_shows_nothing_and_asks_for_it(browser, rig):
    _, web, _ = rig
    _load(browser, web)
    _wait(browser, lambda drv: "paste the token" in _message(browser)[0], what="token asked")
    # the words match the button: the message names the label the button carries
    assert _button_words(browser) in _message(browser)[0]
    assert "open the URL rigd web printed" in _message(browser)[0]
    assert _js(browser, "window.rigd.mode") == "connecting"
    assert _js(browser, "window.rigd.updates") == 0
    assert browser.console_errors() == []         # nothing fetched: no 401 logged


def test_the_printed_url_logs_the_tab_in_and_leaves_the_address_bar(browser, rig):
    """``rigd web``'s one-click URL (``/#token=<control token>``): the console is logged in
    with nothing typed, the token is out of the address bar and kept for the tab only, and it
    commands (what the operator of ``rigd web`` may do): enable → ``rigd ctl status``."""
    d, web, _ = rig
    d.ctl("disable")
    assert "#token=" in web.login_url
    browser.load(web.login_url, "!!window.rigd", what="the console page's scripts")
    _wait(browser, lambda drv: _js(browser, "window.rigd.mode") == "stream",
          what="live stream connected, logged in from the URL")
    assert _js(browser, "location.href") == web.url + "/"
    assert "token" not in _js(browser, "location.hash + location.search")
    assert _js(browser, "sessionStorage.getItem('rigd-token')") == web.token
    assert _js(browser, "localStorage.length") == 0          # the tab's, nothing kept beyond
    assert _js(browser, "window.rigd.access") == "control"
    text, cls = _message(browser)
    assert cls.endswith("ok") and "logged in with the control token" in text
    browser.find_element(By.ID, "enable").click()
    wait_for(lambda: d.ctl_json("status")["controller"]["enabled"], timeout=30,
             what="rigd ctl status: K∞ enabled from the URL-logged-in page")
    _wait(browser, lambda drv: drv.find_element(By.ID, "kinf").text == "on",
          what="page shows K∞ on")
    # a reload of the tab stays logged in (sessionStorage), the address stays clean
    browser.load(browser.current_url, "!!window.rigd", what="the reloaded console page")
    _wait(browser, lambda drv: _js(browser, "window.rigd.mode") == "stream",
          what="live stream connected after a reload")
    assert _js(browser, "location.href") == web.url + "/"
    browser.find_element(By.ID, "disable").click()
    wait_for(lambda: not d.ctl_json("status")["controller"]["requested"], timeout=30,
             what="K∞ disabled")
    assert browser.console_errors() == []


def test_the_read_only_url_logs_in_for_reads_and_a_wrong_token_is_told(browser, rig):
    """The read-only URL logs in with reads only (the page says so); a URL with a wrong token
    is cleaned from the address bar too, and the page says it was refused and which button
    to press, fetching nothing else."""
    _, web, _ = rig
    browser.load(web.read_login_url, "!!window.rigd", what="the console page's scripts")
    _wait(browser, lambda drv: _js(browser, "window.rigd.mode") == "stream",
          what="live stream connected with the read-only token")
    assert _js(browser, "window.rigd.access") == "read"
    assert "read-only token" in _message(browser)[0]
    assert _js(browser, "location.href") == web.url + "/"
    # a new URL pasted into the same tab changes only the fragment (no reload): taken too
    browser.execute_script("location.hash = arguments[0]", "token=" + web.token)
    _wait(browser, lambda drv: _js(browser, "window.rigd.access") == "control",
          what="the control token of a pasted URL taken without a reload")
    assert _js(browser, "location.href") == web.url + "/"
    assert "logged in with the control token" in _message(browser)[0]
    # the tab loaded again with a wrong token in the address: it overrides the kept one
    browser.delete_all_cookies()
    browser.get("about:blank")
    browser.load(web.url + "/#token=not-the-token-at-all", "!!window.rigd",
                 what="the console page's scripts")
    refused = "the token in the address was refused (HTTP 401)"
    _wait(browser, lambda drv: refused in _message(browser)[0], what="refusal shown")
    text, cls = _message(browser)
    assert "error" in cls
    assert _button_words(browser) in text
    assert _js(browser, "location.href") == web.url + "/"
    assert _js(browser, "window.rigd.mode") == "connecting"
    assert _js(browser, "window.rigd.updates") == 0
    errors = browser.take_console_errors()          # the login's 401, logged by Chromium
    assert errors and all("401" in e for e in errors), errors


def test_enable_with_the_read_only_token_is_403_and_nothing_changes(browser, rig):
    d, web, _ = rig
    d.ctl("disable")
    _open(browser, web, token=web.read_token)   # the live view reads; commands are refused
    browser.find_element(By.ID, "enable").click()
    _wait(browser, lambda drv: "(HTTP 403)" in _message(browser)[0], what="403 on the page")
    text, cls = _message(browser)
    assert "error" in cls and "read-only" in text
    # the same request as the page sends it, without the header
    status = browser.execute_async_script(
        "const done = arguments[0];"
        "fetch('/api/enable', {method: 'POST', headers: {'Content-Type': 'application/json'},"
        " body: '{}'}).then(r => done(r.status));")
    assert status == 401
    st = d.ctl_json("status")
    assert not st["controller"]["requested"] and not st["controller"]["enabled"]
    assert browser.find_element(By.ID, "kinf").text.startswith("off")
    # the page's fetches of a 403/401 are logged by Chromium as failed loads: expected here
    errors = browser.take_console_errors()
    assert errors and all("403" in e or "401" in e for e in errors), errors


def test_invalid_experiment_upload_is_one_line_and_the_daemon_is_unharmed(
        browser, screenshot, rig):
    d, web, tmp = rig
    bad = tmp / "bad-upload.yaml"
    bad.write_text(BAD_EXPERIMENT)
    before = d.ctl_json("status")
    _open(browser, web, token=web.token)
    browser.find_element(By.ID, "exp-file").send_keys(str(bad))
    browser.find_element(By.ID, "start").click()
    _wait(browser, lambda drv: "bad-upload.yaml" in _message(browser)[0], what="error shown")
    text, cls = _message(browser)
    assert "error" in cls and "\n" not in text
    assert text.startswith("start: bad-upload.yaml:7: switch_probability: ")
    assert text.endswith("(HTTP 400)")
    screenshot("console-upload-error")
    # the daemon: alive, loop running on, no experiment started, nothing kept
    after = d.ctl_json("status")
    assert after["running"] and after["fault"]["code"] == 0 and after["seq"] > before["seq"]
    assert d.ctl_json("experiment").get("name") != "bad-upload"
    assert not (tmp / "runs" / "uploads").exists() or not any(
        "bad-upload" in p.name for p in (tmp / "runs" / "uploads").iterdir())
    errors = browser.take_console_errors()          # the 400 response, logged by Chromium
    assert all("400" in e for e in errors), errors


def test_safe_button_latches_the_safe_state(browser, rig):
    d, web, _ = rig
    _open(browser, web, token=web.token)
    browser.find_element(By.ID, "safe").click()
    wait_for(lambda: d.ctl_json("status")["fault"]["name"] == "operator_safe", timeout=30,
             what="operator_safe latched")
    _wait(browser, lambda drv: "operator_safe" in drv.find_element(By.ID, "fault").text,
          what="fault text on the page")
    browser.find_element(By.ID, "reset").click()
    wait_for(lambda: d.ctl_json("status")["fault"]["code"] == 0, timeout=30, what="reset")


def test_runs_tab_opens_a_record(browser, screenshot, rig):
    d, web, _ = rig
    _open(browser, web, token=web.token)
    _wait(browser, lambda drv: len(drv.find_elements(By.CSS_SELECTOR, "#exp-select option")) > 2,
          what="experiments listed")
    Select(browser.find_element(By.ID, "exp-select")).select_by_value(
        "config/experiments/web-short.yaml")
    browser.find_element(By.ID, "start").click()
    wait_for(lambda: d.ctl_json("experiment").get("state") == "complete", timeout=120,
             interval=0.3, what="experiment complete")
    browser.find_element(By.ID, "tab-runs").click()
    row = _wait(browser, lambda drv: [r for r in drv.find_elements(
        By.CSS_SELECTOR, "#runs-table tbody tr") if "web-short" in r.get_attribute("data-run")
        and r.find_elements(By.CSS_SELECTOR, "button.open-record")], what="run listed")[0]
    assert "prbs" in row.text and "complete" in row.text and "simulated" in row.text
    row.find_element(By.CSS_SELECTOR, "button.open-record").click()
    _wait(browser, lambda drv: _js(browser, "(document.getElementById('record-plot').data "
                                   "|| []).length") > 0, what="record plotted")
    names = json.loads(_js(browser, "JSON.stringify(document.getElementById('record-plot')"
                                    ".data.map(t => t.name))"))
    assert any(n.startswith("e_x") for n in names)
    assert "samples at 5000" in browser.find_element(By.ID, "record-title").text
    screenshot("console-runs")
