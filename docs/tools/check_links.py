"""Check every internal link of a built HTML site: each relative ``href`` and ``src`` names a file
that exists, and each ``#fragment`` an element id (or ``name``) in the page it points to.

    python docs/tools/check_links.py docs/_build/html

External links (``http:``, ``https:``, ``mailto:``, ...) and ``data:`` URIs are not followed: the
build machine has no network, and they are not ours to keep. Files under ``_static/`` are the
theme's assets (a template among them), not pages, and are not scanned. Exit 1 and one line per broken link
when any is broken. Imports the standard library only.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

LINK_ATTRIBUTES = {"a": "href", "link": "href", "img": "src", "script": "src", "iframe": "src", "source": "src"}


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.links: list[tuple[str, str]] = []  # (tag, url)
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        for key in ("id", "name"):
            if values.get(key):
                self.ids.add(values[key])
        wanted = LINK_ATTRIBUTES.get(tag)
        if wanted and values.get(wanted) is not None:
            self.links.append((tag, values[wanted]))


def _parse(path: Path, cache: dict[Path, _Page]) -> _Page:
    if path not in cache:
        page = _Page()
        page.feed(path.read_text(encoding="utf-8", errors="replace"))
        cache[path] = page
    return cache[path]


def pages(site: str | Path) -> list[Path]:
    """The HTML pages of ``site`` (theme assets under ``_static/`` left out)."""
    site = Path(site)
    return [p for p in sorted(site.rglob("*.html")) if "_static" not in p.relative_to(site).parts]


def broken_links(site: str | Path) -> list[str]:
    """One line per broken internal link of the HTML files under ``site`` (empty: none)."""
    site = Path(site).resolve()
    cache: dict[Path, _Page] = {}
    problems = []
    for page_path in pages(site):
        page = _parse(page_path, cache)
        for tag, url in page.links:
            parts = urlsplit(url)
            if parts.scheme or parts.netloc or url.startswith("//"):
                continue  # external, data:, javascript:, mailto:
            where = f"{page_path.relative_to(site)}: <{tag}> {url}"
            target = page_path if not parts.path else (page_path.parent / unquote(parts.path)).resolve()
            if target.is_dir():
                target = target / "index.html"
            if not target.is_file():
                problems.append(f"{where}: no such file")
                continue
            fragment = unquote(parts.fragment)
            if fragment and target.suffix == ".html" and fragment not in _parse(target, cache).ids:
                problems.append(f"{where}: no element with id {fragment!r} in {target.relative_to(site)}")
    return problems


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: check_links.py SITE_DIR", file=sys.stderr)
        return 2
    site = Path(argv[0])
    found = pages(site)
    if not found:
        print(f"check_links: no HTML pages under {site}", file=sys.stderr)
        return 1
    problems = broken_links(site)
    for p in problems:
        print(p)
    print(f"check_links: {len(found)} pages, {len(problems)} broken internal links", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
