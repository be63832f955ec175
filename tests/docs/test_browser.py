"""The report and the documentation in a real browser (headless Chromium through Selenium).

A small run writes a report: one 6-cycle session of the emulated test bed's twin at 0.6 mm, recorded
through the ``sim`` backend, then ``wearbench compare`` (identification against the shipped ensembles,
window verdicts, figures). ``report.html`` must load with no console errors, every figure must load
(natural width > 0), every table must have rows, and it must print to PDF. The same checks run on
the documentation's landing page and its tutorial, served over HTTP on 127.0.0.1. The checks' own
cases: the same report with one figure removed, one figure that is not an image, and one table
emptied must fail.
"""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
import sys

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

IMG = re.compile(r'<img alt="(?P<alt>[^"]*)" src="(?P<src>[^"]*)"')


def wearbench(*args: str, cwd) -> None:
    run = subprocess.run([sys.executable, "-m", "wearbench.cli", *args], cwd=cwd, capture_output=True, text=True,
                         timeout=1500, check=False)
    assert run.returncode == 0, f"wearbench {' '.join(args)}:\n{run.stderr[-3000:]}"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("report-run")
    (folder / "twin.json").write_text(json.dumps({"signal": "model", "truth": {"twin": True, "state": "0.6 mm new"}}))
    wearbench("record", "ninebar-testbed", "--option", "speedup=inf", "--option", "config=twin.json",
              "--cycles", "6", "--out", "s.mcap", cwd=folder)
    wearbench("compare", "s.mcap", "--out", "report", cwd=folder)
    return folder / "report"


def test_the_report_loads_shows_every_figure_and_table_and_prints(browser, report):
    html = (report / "report.html").read_text(encoding="utf-8")
    figures, tables = len(IMG.findall(html)), html.count("<table")
    assert figures >= 5 and tables >= 2  # identification, windows, bands: what a compare run writes
    page = browser.check((report / "report.html").as_uri(), min_figures=figures, min_tables=tables)
    assert len(page.figures) == figures and len(page.tables) == tables


def _copy(report, tmp_path):
    copy = tmp_path / "report"
    shutil.copytree(report, copy)
    return copy, (copy / "report.html").read_text(encoding="utf-8")


def test_a_report_with_a_figure_removed_fails(browser, report, tmp_path):
    """One figure gone: its <img> names a file (as a report that links its figures does) and that
    file is removed. The figure's natural width is 0 and the check fails."""
    copy, html = _copy(report, tmp_path)
    first = IMG.search(html)
    name = first["alt"] + ".png"
    if first["src"].startswith("data:"):  # figures embedded: the report links this one to its file instead
        html = html.replace(first.group(0), f'<img alt="{first["alt"]}" src="{name}"', 1)
        (copy / "report.html").write_text(html, encoding="utf-8")
    else:
        name = first["src"]
    (copy / name).unlink(missing_ok=True)
    page = browser.open((copy / "report.html").as_uri())
    assert [f for f in page.figures if f[2] == 0 and f[0].endswith(name)], page.figures
    with pytest.raises(AssertionError, match="figures that did not load|console errors"):
        browser.check((copy / "report.html").as_uri())


def test_a_report_with_a_broken_figure_fails(browser, report, tmp_path):
    """One figure's bytes are not an image (a figure file overwritten by something else). (A PNG cut
    short is not caught: Chromium draws what it has, at the full size its header states.)"""
    copy, html = _copy(report, tmp_path)
    first = IMG.search(html)
    garbage = base64.b64encode(b"not a PNG: " + bytes(range(256))).decode()
    if first["src"].startswith("data:"):
        html = html.replace(first["src"], "data:image/png;base64," + garbage, 1)
    else:
        (copy / first["src"]).write_bytes(base64.b64decode(garbage))
    (copy / "report.html").write_text(html, encoding="utf-8")
    with pytest.raises(AssertionError, match="figures that did not load|console errors"):
        browser.check((copy / "report.html").as_uri())


def test_a_report_with_an_empty_table_fails(browser, report, tmp_path):
    copy, html = _copy(report, tmp_path)
    start = html.index("<table")
    end = html.index("</table>", start)
    emptied = html[:start] + re.sub(r"<tr>(?:(?!</tr>).)*<td.*?</tr>", "", html[start:end], flags=re.DOTALL) + html[end:]
    assert emptied != html
    (copy / "report.html").write_text(emptied, encoding="utf-8")
    with pytest.raises(AssertionError, match="a table without rows"):
        browser.check((copy / "report.html").as_uri())


@pytest.mark.parametrize("page", ["index.html", "tutorial/first-week.html"])
def test_the_documentation_in_a_browser(browser, docs_html, serve, page):
    base = serve(docs_html)
    browser.check(base + page, min_figures=1)
