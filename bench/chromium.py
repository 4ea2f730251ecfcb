"""Headless Chromium through selenium 4 (Debian's ``chromium`` + ``chromium-driver``, no
browser download): found here, started here — for the browser tests (tests/browser/) and the
console figures of ``python -m bench web``.

``RIGD_CHROMIUM`` / ``RIGD_CHROMEDRIVER`` override the paths (empty: "not installed", to check
the tests' skip).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from functools import cache

#: seconds for one WebDriver command (starting Chromium included): generous, the machine may
#: be a busy shared one; a test waits on conditions, this only bounds a hung browser
COMMAND_TIMEOUT_S = 300


def _first_executable(*candidates: str | None) -> str | None:
    for c in candidates:
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    return None


@cache
def find_chromium() -> tuple[str | None, str | None, str | None]:
    """``(chromium, chromedriver, version)``; a missing part is ``None``."""
    env_c, env_d = os.environ.get("RIGD_CHROMIUM"), os.environ.get("RIGD_CHROMEDRIVER")
    chromium = (_first_executable(env_c) if env_c is not None else _first_executable(
        "/usr/bin/chromium", shutil.which("chromium"), shutil.which("chromium-browser")))
    driver = (_first_executable(env_d) if env_d is not None else _first_executable(
        "/usr/bin/chromedriver", shutil.which("chromedriver")))
    version = None
    if chromium and driver:
        try:
            out = subprocess.run([driver, "--version"], capture_output=True, text=True,
                                 timeout=30).stdout.split()
            version = out[1] if len(out) > 1 else "?"
        except (OSError, subprocess.SubprocessError):
            driver = None
    return chromium, driver, version


def make_driver():
    """``(driver, service)``: a headless Chromium (1400x1000 window, console log kept, WebGL
    on the software rasterizer). Stop with
    ``driver.quit(); service.stop()``."""
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.chromium.remote_connection import ChromiumRemoteConnection
    from selenium.webdriver.remote.client_config import ClientConfig
    from selenium.webdriver.remote.file_detector import UselessFileDetector

    chromium, chromedriver, _ = find_chromium()
    if not (chromium and chromedriver):
        raise RuntimeError("chromium and chromedriver are needed (apt-get install chromium "
                           "chromium-driver)")
    options = Options()
    options.binary_location = chromium
    # --enable-unsafe-swiftshader: WebGL on the CPU (no GPU here); the pages are our own
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--enable-unsafe-swiftshader", "--window-size=1400,1000", "--no-first-run",
                "--disable-extensions", "--disable-background-networking"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    service = Service(chromedriver)
    service.start()
    try:
        conn = ChromiumRemoteConnection(
            remote_server_addr=service.service_url, vendor_prefix="goog", browser_name="chrome",
            ignore_proxy=True, client_config=ClientConfig(
                remote_server_addr=service.service_url, keep_alive=True,
                timeout=COMMAND_TIMEOUT_S))
        driver = webdriver.Remote(command_executor=conn, options=options)
    except BaseException:
        service.stop()
        raise
    # the driver is local: file inputs get the path itself (a Remote driver would upload the
    # file through the Grid-only se/file command)
    driver.file_detector = UselessFileDetector()
    driver.set_page_load_timeout(120)
    driver.set_script_timeout(120)
    return driver, service
