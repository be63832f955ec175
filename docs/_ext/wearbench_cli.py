"""The ``wearbench`` parser for sphinx-argparse, its help texts made safe for reStructuredText.

``reference/cli.md`` renders ``wearbench.cli.build_parser()``, the very parser the program runs,
through the ``argparse`` directive (``:module: wearbench_cli``, ``:func: parser``). The help texts are
plain text written for a terminal; characters that reStructuredText reads as markup (``|v_t|``
would be a substitution, ``*`` emphasis, a trailing ``_`` a link) are escaped here, on a copy of
each text, so the page shows them as the terminal does. Option strings, choices and defaults are
left as they are: ``tests/docs/test_cli_reference.py`` compares them with ``wearbench --help``.
"""

from __future__ import annotations

import argparse
import re

_MARKUP = re.compile(r"([\\|*`])")
_TRAILING_UNDERSCORE = re.compile(r"(\w)_(?=\W|$)")


def rst_text(text: str | None) -> str | None:
    """``text`` with reStructuredText inline markup characters escaped."""
    if not text or text is argparse.SUPPRESS:
        return text
    return _TRAILING_UNDERSCORE.sub(r"\1\\_", _MARKUP.sub(r"\\\1", text))


def _escape(parser: argparse.ArgumentParser, seen: set[int]) -> None:
    if id(parser) in seen:
        return
    seen.add(id(parser))
    parser.description = rst_text(parser.description)
    parser.epilog = rst_text(parser.epilog)
    for action in parser._actions:
        action.help = rst_text(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:  # the one-line help of each subcommand
                choice.help = rst_text(choice.help)
            for child in action.choices.values():
                _escape(child, seen)


def parser() -> argparse.ArgumentParser:
    """``wearbench.cli.build_parser()`` with its help texts escaped for reStructuredText."""
    from wearbench.cli import build_parser

    p = build_parser()
    _escape(p, set())
    return p


def setup(app):  # a Sphinx extension only so that conf.py lists every docs module in one place
    return {"parallel_read_safe": True, "parallel_write_safe": True}
