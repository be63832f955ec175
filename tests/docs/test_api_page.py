"""The Python API page documents exactly ``wearbench.__all__``, each name reachable as ``wearbench.NAME``.

The page (``docs/reference/api.md``) holds only a directive that reads ``__all__`` at build time; the
built page's object descriptions (``<dt id="wearbench.NAME">``, autodoc's anchors) are compared with
``__all__`` as ``import wearbench`` gives it. Members of classes (``wearbench.Bench.x``) are not
public names and are left out of the comparison.
"""

from __future__ import annotations

import re

import pytest

import wearbench

pytestmark = pytest.mark.no_kernels


def documented(html: str) -> set[str]:
    return set(re.findall(r'<dt class="sig sig-object py" id="wearbench\.([^".]+)"', html))


def test_the_api_page_lists_exactly_all(docs_html):
    html = (docs_html / "reference" / "api.html").read_text(encoding="utf-8")
    names = documented(html)
    assert names, "the API page documents no object"
    assert names == set(wearbench.__all__), (
        f"on the page, not in __all__: {sorted(names - set(wearbench.__all__))}; "
        f"in __all__, not on the page: {sorted(set(wearbench.__all__) - names)}")


def test_every_public_name_resolves_and_has_a_docstring():
    """What the page documents is importable as ``wearbench.NAME`` and says what it is."""
    for name in wearbench.__all__:
        obj = getattr(wearbench, name)
        assert (obj.__doc__ or "").strip(), f"wearbench.{name} has no docstring for the API page"


def test_the_page_generator_follows_all(monkeypatch):
    """The page is generated from ``__all__``, not typed: a name added to ``__all__`` (and one taken
    away) changes what the directive documents, with no edit of the page."""
    import wearbench_api

    before = wearbench_api.api_rst()
    assert "   wearbench.load_bench" in before or "load_bench" not in wearbench.__all__
    monkeypatch.setattr(wearbench, "__all__", [*wearbench.__all__, "extra_name"])
    monkeypatch.setattr(wearbench, "extra_name", lambda: None, raising=False)
    added = wearbench_api.api_rst()
    assert ".. autofunction:: wearbench.extra_name" in added
    monkeypatch.setattr(wearbench, "__all__", [n for n in wearbench.__all__ if n not in ("extra_name", "simulate")])
    removed = "\n".join(wearbench_api.api_rst())
    assert "wearbench.simulate" not in removed and "wearbench.extra_name" not in removed
