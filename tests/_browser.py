"""A headless Chromium for the page tests: Debian's ``/usr/bin/chromium`` driven by Selenium
through ``/usr/bin/chromedriver`` (given explicitly, so Selenium downloads nothing).

:func:`browser` yields a driver that logs the console (``goog:loggingPrefs``) and every network
request (the performance log); :func:`console_errors` and :func:`requests` read them.
"""

from __future__ import annotations

import contextlib
import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
#: A laptop screen [CSS px].
WINDOW = (1440, 900)

#: JavaScript: every canvas in the document, its shadow roots included, with its size and the
#: fraction of its pixels that are not blank (white or transparent).
CANVASES_JS = """
const found = [];
const walk = (root) => {
  for (const el of root.querySelectorAll('*')) {
    if (el.tagName === 'CANVAS') found.push(el);
    if (el.shadowRoot) walk(el.shadowRoot);
  }
};
walk(document);
return found.map((c) => {
  let inked = 0, total = 0;
  try {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    for (let i = 0; i < d.length; i += 4 * 7) {
      total += 1;
      if (d[i + 3] > 0 && (d[i] < 235 || d[i + 1] < 235 || d[i + 2] < 235)) inked += 1;
    }
  } catch (e) { return {width: c.width, height: c.height, inked: -1}; }
  return {width: c.width, height: c.height, inked: total ? inked / total : 0};
});
"""

#: JavaScript: the Bokeh documents' plots and whether each has a view rendered on the page.
PLOTS_JS = """
if (typeof Bokeh === 'undefined') return null;
const out = [];
for (const doc of Bokeh.documents) {
  for (const model of doc._all_models.values()) {
    const type = model.type || model.constructor.__name__;
    if (type === 'Figure' || type === 'Plot' || type === 'DataTable') {
      out.push({type: type, id: model.id});
    }
  }
}
const views = [];
for (const root of Object.values(Bokeh.index)) {
  for (const v of root.owner.all_views()) views.push(v.model.id);
}
return {plots: out, views: views};
"""

#: JavaScript: every src/href in the document (shadow roots included).
LINKS_JS = """
const found = [];
const walk = (root) => {
  for (const el of root.querySelectorAll('*')) {
    for (const a of ['src', 'href']) {
      if (el.getAttribute && el.getAttribute(a)) found.push(el.getAttribute(a));
    }
    if (el.shadowRoot) walk(el.shadowRoot);
  }
};
walk(document);
return found;
"""


def require_chromium() -> None:
    """Skip the test when Chromium or its driver is missing (``apt-get install chromium
    chromium-driver``)."""
    for path in (CHROMIUM, CHROMEDRIVER):
        if not Path(path).exists() and shutil.which(Path(path).name) is None:
            pytest.skip(f"{path} missing: apt-get install -y chromium chromium-driver")


@contextlib.contextmanager
def browser() -> Iterator[Any]:
    """A headless Chromium (Selenium WebDriver) that logs the console and the network."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    require_chromium()
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--disable-gpu",
        f"--window-size={WINDOW[0]},{WINDOW[1]}",
        "--hide-scrollbars",
    ):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def open_page(driver: Any, path: Path, timeout_s: float = 60.0) -> None:
    """Load ``path`` and wait until Bokeh has rendered every root (or the page has none)."""
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(path.resolve().as_uri())
    WebDriverWait(driver, timeout_s).until(
        lambda d: d.execute_script(
            "return document.readyState === 'complete' && (typeof Bokeh === 'undefined' || "
            "(Bokeh.documents.length > 0 && Object.keys(Bokeh.index).length > 0));"
        )
    )
    driver.execute_script("return new Promise(r => setTimeout(r, 500));")


def console_errors(driver: Any) -> list[str]:
    """The console messages of level SEVERE (JavaScript errors, failed loads)."""
    return [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def requests(driver: Any) -> list[str]:
    """The URLs of every request the page made (the performance log)."""
    urls = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        if message["method"] == "Network.requestWillBeSent":
            urls.append(message["params"]["request"]["url"])
    return urls


def screenshot(driver: Any, path: Path, width: int = WINDOW[0]) -> None:
    """A PNG of the whole page (the window stretched to its height)."""
    height = driver.execute_script("return document.documentElement.scrollHeight")
    driver.set_window_size(width, min(int(height) + 40, 6000))
    driver.execute_script("return new Promise(r => setTimeout(r, 700));")
    path.parent.mkdir(parents=True, exist_ok=True)
    driver.save_screenshot(str(path))
    driver.set_window_size(*WINDOW)
