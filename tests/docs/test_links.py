"""Internal links: every link and image of the built site, and every relative link of the README,
points at something that exists; the checker itself catches a missing page, anchor and image."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import check_links
import pytest

pytestmark = pytest.mark.no_kernels

ROOT = Path(__file__).resolve().parents[2]


def test_the_built_site_has_no_broken_internal_link(docs_html):
    assert len(check_links.pages(docs_html)) >= 20
    assert check_links.broken_links(docs_html) == []


def test_the_checker_finds_a_missing_page_anchor_and_image(tmp_path):
    site = tmp_path / "site"
    (site / "a").mkdir(parents=True)
    (site / "index.html").write_text('<a href="a/page.html#there">ok</a><a href="#top">self</a><p id="top"></p>'
                                     '<a href="https://example.invalid/">external</a><img src="data:image/png;base64,AA">')
    (site / "a" / "page.html").write_text('<h1 id="there">x</h1><a href="../index.html">up</a><img src="fig.png">')
    (site / "a" / "fig.png").write_bytes(b"\x89PNG")
    assert check_links.broken_links(site) == []
    (site / "a" / "fig.png").unlink()
    (site / "index.html").write_text('<a href="a/gone.html">x</a><a href="a/page.html#nowhere">y</a>')
    found = check_links.broken_links(site)
    assert any("a/gone.html: no such file" in f for f in found)
    assert any("no element with id 'nowhere'" in f for f in found)
    assert any("fig.png: no such file" in f for f in found)
    shutil.rmtree(site)


def test_every_relative_link_of_the_readme_exists():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    relative = [t for t in targets if not re.match(r"^[a-z]+:", t)]
    assert relative, "the README links into the documentation"
    missing = [t for t in relative if not (ROOT / t).exists()]
    assert not missing, f"README links to files that do not exist: {missing}"
