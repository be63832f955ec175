"""Fixtures of the documentation tests: the built site, and a real browser.

``docs_html`` builds ``docs/`` once per run with warnings as errors, into a temporary folder (the
source tree gets nothing). ``page_check`` opens a page in Chromium (Debian's ``chromium`` and
``chromium-driver``, driven by Selenium) and checks what a reader needs: the page loads with no
console errors, every figure loads (natural width > 0), every table has rows, and the page prints
to PDF. Without a browser the browser tests skip and say why; ``.ci/run`` installs one and sets
``WEARBENCH_REQUIRE_BROWSER=1``, which turns that skip into a failure.
"""

from __future__ import annotations

import base64
import functools
import http.server
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
for folder in (DOCS / "tools", DOCS / "_ext"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

CHROMIUM = ("chromium", "chromium-browser", "google-chrome")


def _missing(reason: str) -> None:
    if os.environ.get("WEARBENCH_REQUIRE_BROWSER") == "1":
        pytest.fail(f"{reason} (WEARBENCH_REQUIRE_BROWSER=1: CI installs the browser)", pytrace=False)
    pytest.skip(reason)


@pytest.fixture(scope="session")
def docs_html(tmp_path_factory) -> Path:
    """The documentation, built with ``-W --keep-going`` (warnings are errors) into a temporary folder."""
    pytest.importorskip("sphinx", reason="the documentation tools are not installed (pip install -e '.[docs]')")
    pytest.importorskip("myst_parser", reason="myst-parser is not installed (pip install -e '.[docs]')")
    out = tmp_path_factory.mktemp("docs") / "html"
    build = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                            "-d", str(out.parent / "doctrees"), str(DOCS), str(out)],
                           capture_output=True, text=True, timeout=1200, check=False)
    assert build.returncode == 0, f"the documentation does not build cleanly:\n{build.stderr[-6000:]}"
    return out


@dataclass
class PageReport:
    console_errors: list[str]
    figures: list[tuple[str, bool, int]]  # (src, complete, natural width)
    tables: list[int]  # rows with data cells, per table
    pdf: bytes


class Browser:
    """A headless Chromium driven by Selenium, one per test run."""

    def __init__(self, driver):
        self.driver = driver

    def open(self, url: str) -> PageReport:
        """Load ``url``, wait for every figure, and read what the checks need."""
        from selenium.webdriver.common.print_page_options import PrintOptions
        from selenium.webdriver.support.ui import WebDriverWait

        d = self.driver
        d.get_log("browser")  # forget what an earlier page logged
        d.get(url)
        WebDriverWait(d, 60).until(lambda drv: drv.execute_script("return document.readyState") == "complete")
        figures = d.execute_async_script("""
            const done = arguments[arguments.length - 1];
            const images = Array.from(document.images);
            images.forEach(i => { i.loading = 'eager'; });
            Promise.all(images.map(i => i.complete ? Promise.resolve() :
                new Promise(r => { i.addEventListener('load', r); i.addEventListener('error', r); })))
              .then(() => done(images.map(i => [(i.currentSrc || i.src).slice(0, 120), i.complete, i.naturalWidth])));
        """)
        tables = d.execute_script("""
            return Array.from(document.querySelectorAll('table')).map(
                t => Array.from(t.querySelectorAll('tr')).filter(r => r.querySelector('td')).length);
        """)
        errors = [e["message"] for e in d.get_log("browser") if e.get("level") == "SEVERE"]
        pdf = base64.b64decode(d.print_page(PrintOptions()))
        return PageReport(errors, [tuple(f) for f in figures], list(tables), pdf)

    def check(self, url: str, *, min_figures: int = 0, min_tables: int = 0) -> PageReport:
        """:meth:`open` ``url`` and assert what a reader needs; AssertionError names what failed."""
        page = self.open(url)
        assert not page.console_errors, f"{url}: console errors: {page.console_errors}"
        assert len(page.figures) >= min_figures, f"{url}: {len(page.figures)} figures, expected at least {min_figures}"
        broken = [src for src, complete, width in page.figures if not (complete and width > 0)]
        assert not broken, f"{url}: figures that did not load: {broken}"
        assert len(page.tables) >= min_tables, f"{url}: {len(page.tables)} tables, expected at least {min_tables}"
        assert all(n > 0 for n in page.tables), f"{url}: a table without rows (rows per table: {page.tables})"
        assert page.pdf.startswith(b"%PDF-"), f"{url}: printing did not give a PDF"
        pages = len(re.findall(rb"/Type\s*/Page(?!s)", page.pdf))
        assert pages >= 1, f"{url}: the printed PDF has no pages"
        return page


@pytest.fixture(scope="session")
def browser():
    """Headless Chromium through Selenium and chromedriver; skipped, with the reason, without them."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        _missing("selenium is not installed (pip install -e '.[test]')")
    binary = next((shutil.which(name) for name in CHROMIUM if shutil.which(name)), None)
    if binary is None:
        _missing("no Chromium installed (Debian: apt-get install chromium chromium-driver)")
    driver_path = shutil.which("chromedriver")
    if driver_path is None:
        _missing("no chromedriver installed (Debian: apt-get install chromium-driver)")
    profile = Path(tempfile.mkdtemp(prefix="wearbench-chromium-"))
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", f"--user-data-dir={profile}", "--window-size=1280,1024"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=Service(driver_path))
    driver.set_page_load_timeout(120)
    driver.set_script_timeout(120)
    try:
        yield Browser(driver)
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture(scope="session")
def serve():
    """``serve(folder)`` -> the base URL of ``folder`` served over HTTP on 127.0.0.1 (closed at the end)."""
    servers = []

    def start(folder: Path) -> str:
        handler = functools.partial(_QuietHandler, directory=str(folder))
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        servers.append(server)
        return f"http://127.0.0.1:{server.server_address[1]}/"

    yield start
    for server in servers:
        server.shutdown()
        server.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass
