"""The interactive report pages in headless Chromium: ``rigd diagnose --report`` and
``rigd compare --report`` written by the CLI, opened from file:// (no server, no internet) and
served over HTTP by ``rigd web``'s app; no console errors; toggling an effect changes the
shown fit to the number ``diagnose`` printed for that model; the compare page zooms.

Records are generated here (tests/diagnose/benchmarks.py Duffing oscillator, where diagnose
adds cubic_stiffness; tests/ident/ident_helpers.py rotor with run-out and shaft angle).
Screenshots go to test-artifacts/screenshots/ (diagnose_report.png is docs/img/diagnose.png).
"""

from __future__ import annotations

import json
import socket
import sys
import threading
from pathlib import Path

import pytest
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from rigd.cli import main
from rigd.data.csvio import write_csv

TESTS = Path(__file__).parents[1]
sys.path.insert(0, str(TESTS / "diagnose"))
sys.path.insert(0, str(TESTS / "ident"))
import benchmarks as B  # noqa: E402  tests/diagnose/benchmarks.py
from ident_helpers import rotor_record  # noqa: E402

WAIT_S = 120    # generous: a 5 MB page on a 2-core machine shared by eight test runs


@pytest.fixture(scope="module")
def diagnose_report(tmp_path_factory):
    """``rigd diagnose REC --report DIR --json`` on a Duffing record: (DIR, its JSON)."""
    d = tmp_path_factory.mktemp("diagnose")
    write_csv(d / "duffing.csv", B.duffing(seed=5, n=3000))
    out = d / "runs" / "diag_report"
    js = _cli_json(["diagnose", str(d / "duffing.csv"), "--effects", "cubic_stiffness,delay",
                    "--order", "2", "--report", str(out), "--json"])
    return out, js


@pytest.fixture(scope="module")
def compare_report(tmp_path_factory):
    """``rigd identify`` then ``rigd compare MODEL REC2 --report DIR`` on rotor records."""
    d = tmp_path_factory.mktemp("compare")
    write_csv(d / "a.csv", rotor_record(n=4000, seed=11, omega_rpm=3000, runout=1.0))
    write_csv(d / "b.csv", rotor_record(n=4000, seed=12, omega_rpm=3000, runout=1.0))
    _cli_json(["identify", str(d / "a.csv"), "--model", "bearing", "-o", str(d / "m.yaml"),
               "--json"])
    out = d / "cmp_report"
    js = _cli_json(["compare", str(d / "m.yaml"), str(d / "b.csv"), "--report", str(out),
                    "--json"])
    return out, js


def _cli_json(argv: list[str]) -> dict:
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(argv) == 0
    return json.loads(buf.getvalue())


def _open(browser, url: str) -> None:
    browser.load(url, "document.body && document.body.getAttribute('data-ready') === '1'",
                 WAIT_S, "the report page")


def _fit_shown(browser, part: str = "generic") -> float:
    """The fit the page shows, read from its text ("97.75 %")."""
    text = browser.find_element(By.ID, f"fit-{part}").text
    return float(text.replace("%", "").strip())


def _trace_names(browser, div: str) -> list[str]:
    return browser.execute_script(
        f"return document.getElementById('{div}').data.map(function (t) {{ return t.name; }})")


def test_diagnose_report_from_file_url_toggles_effects(browser, screenshot, diagnose_report):
    out, js = diagnose_report
    base_fit, step_fit = (s["fit_percent"] for s in js["steps"])
    delay_fit = next(f["fit_percent_with"] for f in js["findings"] if f["effect"] == "delay")
    assert js["steps"][1]["added"] == "cubic_stiffness" and step_fit > base_fit + 10
    _open(browser, (out / "index.html").as_uri())
    assert browser.console_errors() == []
    # first shown: the final model of the forward selection, with its effect switched on
    cubic = browser.find_element(By.ID, "toggle-generic-cubic_stiffness")
    delay = browser.find_element(By.ID, "toggle-generic-delay")
    assert cubic.is_selected() and not delay.is_selected()
    assert _fit_shown(browser) == pytest.approx(step_fit, abs=0.006)
    names = _trace_names(browser, "time-generic")
    assert any(n.startswith("+ cubic_stiffness") for n in names)
    assert "residual y_mm, base model" in names        # the error before, beside after
    # an unexplained frequency band diagnose reported is shaded on the residual spectrum
    banded = any("band_hz" in u["where"] for u in js["unexplained"])
    assert ("unexplained band" in _trace_names(browser, "spectrum-generic")) == banded
    browser.driver.set_window_size(1400, 1700)
    screenshot("diagnose_report")
    # switch cubic_stiffness off: the base model, its fit, and its curve on the plot
    cubic.click()
    WebDriverWait(browser.driver, WAIT_S).until(
        lambda d: abs(_fit_shown(browser) - base_fit) < 0.006)
    assert "base model" in browser.find_element(By.ID, "label-generic").text
    assert not any(n.startswith("+ cubic") for n in _trace_names(browser, "time-generic"))
    screenshot("diagnose_report_base")
    # delay alone was not fitted by diagnose: the page says so, the shown model stays
    delay.click()
    WebDriverWait(browser.driver, WAIT_S).until(
        lambda d: "did not fit" in d.find_element(By.ID, "msg-generic").text)
    assert _fit_shown(browser) == pytest.approx(base_fit, abs=0.006)
    # both on: the final model + delay as diagnose refitted it (its fit_percent_with)
    cubic.click()
    WebDriverWait(browser.driver, WAIT_S).until(
        lambda d: abs(_fit_shown(browser) - delay_fit) < 0.006)
    assert browser.find_element(By.ID, "msg-generic").text == ""
    # a step of the table shows that step's model and sets the switches to it
    browser.find_elements(By.CSS_SELECTOR, "#steps-generic tr.step")[1].click()
    WebDriverWait(browser.driver, WAIT_S).until(
        lambda d: abs(_fit_shown(browser) - step_fit) < 0.006)
    assert cubic.is_selected() and not delay.is_selected()
    assert browser.console_errors() == []


def test_compare_report_overlay_zoom_and_polar(browser, screenshot, compare_report):
    out, js = compare_report
    _open(browser, (out / "index.html").as_uri())
    names = _trace_names(browser, "time-bearing")
    for o in ("e_x", "e_y"):
        assert f"measured {o}" in names and f"model {o}" in names
    assert any("resonance" in n for n in _trace_names(browser, "spectrum-bearing"))
    assert len(_trace_names(browser, "polar-bearing")) == 2       # φ in the record
    shown = [float(td.text) for td in browser.find_elements(
        By.CSS_SELECTOR, "#part-bearing table tr td:nth-child(2)")]
    assert shown == pytest.approx(list(js["fit_per_output"]["bearing"].values()), abs=0.006)
    # drag across the middle of the upper plot: the time axis zooms in
    plot = browser.find_element(By.CSS_SELECTOR, "#time-bearing .nsewdrag")
    full = browser.execute_script(
        "return document.getElementById('time-bearing').layout.xaxis.range.slice()")
    w = plot.size["width"]
    ActionChains(browser.driver).move_to_element_with_offset(plot, -w // 8, 0) \
        .click_and_hold().move_by_offset(w // 4, 0).release().perform()
    WebDriverWait(browser.driver, WAIT_S).until(lambda d: d.execute_script(
        "return document.getElementById('time-bearing').layout.xaxis.autorange") is False)
    zoom = browser.execute_script(
        "return document.getElementById('time-bearing').layout.xaxis.range.slice()")
    assert full[0] < zoom[0] < zoom[1] < full[1]
    assert zoom[1] - zoom[0] < 0.5 * (full[1] - full[0])
    screenshot("compare_report_zoomed")
    assert browser.console_errors() == []


def test_reports_work_served_by_rigd_web(browser, screenshot, diagnose_report, tmp_path):
    """The same folder under the runs folder, served by rigd web's app over HTTP: the page,
    its PNG figures (relative names) and the toggles work; no console errors."""
    uvicorn = pytest.importorskip("uvicorn")
    from rigd.web.app import Settings, build_app

    out, js = diagnose_report
    settings = Settings(socket=str(tmp_path / "no-daemon.sock"), runs_dir=out.parent,
                        config_dir=tmp_path, token="t" * 32)
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(build_app(settings), log_level="warning"))
    th = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    th.start()
    try:
        WebDriverWait(browser.driver, WAIT_S).until(lambda d: server.started)
        # reads need the token: the console page's login exchange sets the session cookie
        browser.load(f"http://127.0.0.1:{port}/", "document.readyState === 'complete'",
                     WAIT_S, "the console page")
        assert browser.execute_async_script(
            "const done = arguments[1]; fetch('/api/login', {method: 'POST', headers: "
            "{Authorization: 'Bearer ' + arguments[0]}}).then(r => done(r.status));",
            settings.token) == 200
        _open(browser, f"http://127.0.0.1:{port}/runs/{out.name}/index.html")
        browser.find_element(By.CSS_SELECTOR, "#figures summary").click()
        WebDriverWait(browser.driver, WAIT_S).until(lambda d: d.execute_script(
            "var im = document.querySelectorAll('figure img'); return im.length > 0 && "
            "Array.prototype.every.call(im, function (i) { return i.complete && "
            "i.naturalWidth > 0; })"))
        browser.find_element(By.ID, "toggle-generic-cubic_stiffness").click()
        WebDriverWait(browser.driver, WAIT_S).until(
            lambda d: abs(_fit_shown(browser) - js["steps"][0]["fit_percent"]) < 0.006)
        screenshot("diagnose_report_http")
        assert browser.console_errors() == []
    finally:
        server.should_exit = True
        th.join(timeout=WAIT_S)
        sock.close()
    assert not th.is_alive()
