"""Browser-test fixtures: a headless Chromium driven by selenium 4 (Debian's ``chromium`` +
``chromium-driver``; no browser download), its console errors, and screenshots.

Use::

    def test_page(browser, screenshot):
        browser.load(url, "window.myPageReady")   # or browser.get(url) for a small page
        ...
        screenshot("console")          # -> test-artifacts/screenshots/console.png
        assert browser.console_errors() == []

Every test using ``browser`` fails at teardown when the page logged a console error
(``SEVERE``) that the test did not take with ``browser.take_console_errors()``; a test that
expects errors takes them. Without chromium/chromedriver the tests are skipped with the
reason (also printed in pytest's header).
``RIGD_CHROMIUM=`` (empty) shows the skip on a machine that has them.
"""

from __future__ import annotations

import pytest
from browserkit import screenshot_path, skip_reason
from selenium.common.exceptions import TimeoutException
from selenium.webdriver.support.ui import WebDriverWait

from bench.chromium import make_driver

# pytest's header line ("browser tests: run with chromium X" / "... SKIPPED (...)") comes
# from tests/conftest.py: a hook here would only run when pytest starts in tests/browser.


class Browser:
    """A selenium ``WebDriver`` (attribute access passes through) plus its console log."""

    def __init__(self, driver):
        self.driver = driver
        self._log: list[dict] = []

    def __getattr__(self, name):
        return getattr(self.driver, name)

    def _drain(self) -> None:
        # ChromiumDriver.get_log's command, through the Chromium connection (a Remote driver
        # with a longer command timeout has no get_log method of its own)
        self._log.extend(self.driver.execute("getLog", {"type": "browser"})["value"])

    def console_log(self) -> list[dict]:
        """Every console entry so far (``level``, ``message``, ``timestamp``)."""
        self._drain()
        return list(self._log)

    def console_errors(self) -> list[str]:
        """Messages of the ``SEVERE`` entries (console.error, uncaught exceptions, failed
        loads) so far."""
        return [e["message"] for e in self.console_log() if e.get("level") == "SEVERE"]

    def load(self, url: str, ready: str, timeout: float = 300.0, what: str = "the page"):
        """Navigate to ``url`` and wait until the script expression ``ready`` is truthy (a
        marker the page sets once its scripts have run); returns its value. A page slower to
        load than the driver's page-load timeout (parsing Plotly's 3.5 MB on a machine busy
        with other jobs) is no error: it goes on loading, and ``timeout`` (s) bounds the wait
        on ``ready`` — a page that never gets there fails the test saying ``what``, it never
        hangs it."""
        try:
            self.driver.get(url)
        except TimeoutException:
            pass
        return WebDriverWait(self.driver, timeout, poll_frequency=0.1).until(
            lambda drv: drv.execute_script("return " + ready), message=f"{what} at {url}")

    def take_console_errors(self) -> list[str]:
        """Like ``console_errors`` and forget them (for tests that expect errors)."""
        errors = self.console_errors()
        self._log = [e for e in self._log if e.get("level") != "SEVERE"]
        return errors


@pytest.fixture
def browser():
    """A fresh headless Chromium per test; fails the test on untaken console errors."""
    reason = skip_reason()
    if reason:
        pytest.skip(reason)
    driver, service = make_driver()
    b = Browser(driver)
    try:
        yield b
        errors = b.console_errors()
    finally:
        try:
            driver.quit()
        finally:
            service.stop()
    assert not errors, f"browser console errors: {errors}"


@pytest.fixture
def screenshot(browser):
    """``screenshot(name)`` saves the browser's viewport to
    ``test-artifacts/screenshots/<name>.png`` and returns the path."""

    def take(name: str):
        path = screenshot_path(name)
        if not browser.driver.save_screenshot(str(path)):
            raise AssertionError(f"screenshot {name}: chromium wrote nothing")
        return path

    return take
