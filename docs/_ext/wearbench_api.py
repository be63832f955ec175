"""The ``wearbench-api`` directive: the public Python API, generated from ``wearbench.__all__``.

``reference/api.md`` holds only the directive (inside ``{eval-rst}``: autodoc writes reStructuredText,
and docstrings are reStructuredText). At each build it imports ``wearbench``, reads
``__all__`` (the contract of the public API) and documents every name in it through autodoc, as
``wearbench.NAME``: functions, then classes, then exceptions, each group led by an autosummary
table. A name added to or removed from ``__all__`` appears on or leaves the page with no edit here;
a module that moves behind a name changes nothing either, since autodoc reaches every object through
``wearbench`` itself. ``tests/docs/test_api_page.py`` checks that the built page documents exactly
``__all__``.

Docstrings are read as reStructuredText; the package's are mostly plain text, where ``|a|`` means an
absolute value, not a substitution. :func:`plain_bars` escapes such bars (outside literals) before
autodoc parses a docstring, so a docstring written for the terminal does not break the build.
"""

from __future__ import annotations

import importlib
import inspect
import re

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

_LITERAL = re.compile(r"(``.+?``)")
_BARS = re.compile(r"(?<![\\|])\|(?=[^\s|])([^|\n]*?[^\s|\\])\|(?!\|)")


def plain_bars(lines: list[str]) -> None:
    """Escape ``|text|`` (not a substitution: an absolute value, a norm) in docstring ``lines``,
    in place; literals (````...````) are left alone."""
    for i, line in enumerate(lines):
        parts = _LITERAL.split(line)
        lines[i] = "".join(part if part.startswith("``") else _BARS.sub(r"\\|\1\\|", part) for part in parts)


def _process_docstring(app, what, name, obj, options, lines) -> None:
    if name == "wearbench" or name.startswith("wearbench."):
        plain_bars(lines)


GROUPS = (("Functions", "autofunction"), ("Classes", "autoclass"), ("Exceptions", "autoexception"),
          ("Other names", "autodata"))


def kind(obj: object) -> str:
    """The autodoc directive for ``obj``."""
    if inspect.isclass(obj):
        return "autoexception" if issubclass(obj, BaseException) else "autoclass"
    if callable(obj):
        return "autofunction"
    return "autodata"


def public_names(package: str = "wearbench") -> list[str]:
    """``package.__all__``, in its order."""
    return list(importlib.import_module(package).__all__)


def api_rst(package: str = "wearbench") -> list[str]:
    """reStructuredText documenting every name of ``package.__all__``, grouped by kind."""
    module = importlib.import_module(package)
    by_kind: dict[str, list[str]] = {}
    for name in public_names(package):
        by_kind.setdefault(kind(getattr(module, name)), []).append(name)
    lines: list[str] = []
    for title, directive in GROUPS:
        names = by_kind.get(directive, [])
        if not names:
            continue
        lines += [title, "-" * len(title), "", ".. autosummary::", "   :nosignatures:", ""]
        lines += [f"   {package}.{name}" for name in names]
        lines.append("")
        for name in names:
            lines.append(f".. {directive}:: {package}.{name}")
            if directive in ("autoclass", "autoexception"):
                lines.append("   :members:")
            lines.append("")
    return lines


class WearbenchApi(SphinxDirective):
    """``.. wearbench-api::``: every name of ``wearbench.__all__``, through autodoc."""

    has_content = False
    optional_arguments = 1  # the package (default wearbench)

    def run(self) -> list[nodes.Node]:
        package = self.arguments[0] if self.arguments else "wearbench"
        self.env.note_dependency(inspect.getfile(importlib.import_module(package)))
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(api_rst(package), source="wearbench.__all__"), container)
        return container.children


def setup(app):
    app.add_directive("wearbench-api", WearbenchApi)
    app.connect("autodoc-process-docstring", _process_docstring)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
