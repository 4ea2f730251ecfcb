"""The browser fixture itself: a real page in headless Chromium, its console errors, a
screenshot (file:// pages; no server needed)."""

from pathlib import Path

PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>harness</title></head>
<body><p id="out">static</p><script>
document.getElementById('out').textContent = 'scripted ' + (6 * 7);
%s
</script></body></html>"""


def _page(tmp_path: Path, script: str = "") -> str:
    f = tmp_path / "page.html"
    f.write_text(PAGE % script, encoding="utf-8")
    return f.as_uri()


def test_page_runs_its_script_and_screenshot_is_a_png(browser, screenshot, tmp_path):
    browser.load(_page(tmp_path), "document.getElementById('out').textContent === 'scripted 42'",
                 30, "the scripted page")
    path = screenshot("harness")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000
    assert browser.console_errors() == []


def test_console_errors_are_collected(browser, tmp_path):
    browser.load(_page(tmp_path, "console.error('boom from the page'); undefinedCall();"),
                 "document.getElementById('out').textContent === 'scripted 42'", 30,
                 "the scripted page")
    errors = browser.take_console_errors()
    assert any("boom from the page" in e for e in errors), errors
    assert any("undefinedCall" in e for e in errors), errors
    assert browser.console_errors() == []   # taken: the fixture's teardown check passes
