"""``demo-out/index.html`` in headless Chromium: the story page of a real ``rigd demo --quick``
run (the default, physics-grade plant) opened from file:// loads with no console error, every
figure on it renders (decoded, non-zero size on the page) and every link resolves to a file
of the demo's output folder. The page's sections are the story's steps, in order."""

from __future__ import annotations

import json
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest
from selenium.webdriver.common.by import By

WAIT_S = 120


@pytest.fixture(scope="module")
def demo_out(quick_demo):
    """``rigd demo --quick``'s folder: made once per test run (tests/conftest.py), the one
    tests/design/test_demo_e2e.py checks."""
    return quick_demo


def test_demo_page_loads_every_figure_renders_every_link_resolves(browser, screenshot,
                                                                  demo_out):
    page = demo_out / "index.html"
    browser.load(page.as_uri(), "document.readyState === 'complete'", WAIT_S, "the demo page")
    headings = [h.text for h in browser.find_elements(By.TAG_NAME, "h2")]
    assert [h.split(".")[0] for h in headings] == ["1", "2", "3", "4", "5", "6"], headings
    for word, k in (("Records", 0), ("measurement", 1), ("Diagnosis", 2), ("error falls", 3),
                    ("Figs. 3–5", 4), ("Figs. 6–7", 5)):
        assert word in headings[k], (word, headings[k])
    imgs = browser.execute_script(
        "return Array.prototype.map.call(document.images, function (i) { var r = "
        "i.getBoundingClientRect(); return [i.getAttribute('src'), i.complete, "
        "i.naturalWidth, i.naturalHeight, r.width, r.height]; })")
    srcs = [i[0] for i in imgs]
    for need in ("records.png", "heldout.png", "design/weights.png", "design/sensitivity.png",
                 "design/controller.png", "compare_before/bearing_time_zoom.png"):
        assert need in srcs, (need, srcs)
    assert any(s.startswith("diagnose/") for s in srcs)
    assert sum(s.startswith("impact_report/") for s in srcs) == 4
    for src, complete, nw, nh, w, h in imgs:
        assert complete and nw > 0 and nh > 0 and w > 0 and h > 0, (src, nw, nh, w, h)
    hrefs = browser.execute_script(
        "return Array.prototype.map.call(document.links, function (a) { return a.href; })")
    assert len(hrefs) > 10
    for href in hrefs:
        u = urlparse(href)
        assert u.scheme == "file", href                       # relative: inside the folder
        target = Path(unquote(u.path))
        assert target.is_file(), href
        assert demo_out in target.parents, href
    browser.driver.set_window_size(1200, 1600)
    screenshot("demo_page")
    assert browser.console_errors() == []


def test_demo_page_shows_what_the_summary_says(browser, demo_out):
    """The diagnosis section names what summary.json names; the error table shows its
    held-out fits."""
    s = json.loads((demo_out / "summary.json").read_text())
    browser.load((demo_out / "index.html").as_uri(), "document.readyState === 'complete'",
                 WAIT_S, "the demo page")
    text = browser.find_element(By.TAG_NAME, "body").text
    for name in s["diagnosis"]["named"]:
        assert name in text
    for sub, fit in s["diagnosis"]["fit_after"].items():
        assert f"{fit:.2f}" in text, sub
    # the design section says which named effects the design model carries
    for sub, eff in s["design_model_effects"].items():
        for name in eff["included"] + list(eff["left_out"]):
            assert name in text.split("H∞ design on the improved model")[1], (sub, name)
    assert browser.console_errors() == []
