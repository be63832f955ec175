"""The CLI reference lists every subcommand and option that ``wearbench --help`` shows.

The truth is the program's own help, ``wearbench --help`` and ``wearbench COMMAND --help`` (and deeper,
for ``bench VERB``) as the program prints it (``wearbench.cli.main``, in this process: one start
instead of twenty); the page is the built ``reference/cli.html``.
Each command's options must appear in that command's own section of the page, so an option listed
under the wrong command does not count. ``-h/--help`` is every command's and the page leaves it out.
"""

from __future__ import annotations

import contextlib
import io
import re
from html.parser import HTMLParser

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.no_kernels]  # builds the documentation first (CI runs it)

HELP = {"-h", "--help"}
OPTION = re.compile(r"(?<![\w-])(--?[A-Za-z0-9][\w-]*)")


def help_text(*command: str) -> str:
    """What ``wearbench COMMAND --help`` prints (argparse exits 0 after printing it)."""
    from wearbench.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as done:
        main([*command, "--help"])
    assert done.value.code == 0
    return out.getvalue()


def sections(text: str) -> dict[str, list[str]]:
    """The help's sections ("positional arguments", "options", group titles) and their lines."""
    out: dict[str, list[str]] = {}
    current = None
    for line in text.splitlines():
        if line and not line.startswith(" ") and line.endswith(":"):
            current = out.setdefault(line[:-1], [])
        elif current is not None and line.strip():
            current.append(line)
    return out


def parse_help(text: str) -> tuple[set[str], list[str]]:
    """(options, subcommands) of one command's help."""
    options, subcommands = set(), []
    for title, lines in sections(text).items():
        for line in lines:
            invocation = re.match(r"^  (-\S.*?)(?:\s{2,}|$)", line)
            if invocation:
                options |= set(OPTION.findall(invocation.group(1)))
            elif title == "positional arguments":
                sub = re.match(r"^    ([a-z][\w-]*)(?:\s|$)", line)
                if sub:
                    subcommands.append(sub.group(1))
    return options - HELP, subcommands


def program_commands() -> dict[tuple[str, ...], set[str]]:
    """Every command path of the program (() is ``wearbench`` itself) with its options."""
    found: dict[tuple[str, ...], set[str]] = {}
    todo: list[tuple[str, ...]] = [()]
    while todo:
        path = todo.pop(0)
        options, subcommands = parse_help(help_text(*path))
        found[path] = options
        todo += [(*path, s) for s in subcommands]
    return found


class _Reference(HTMLParser):
    """Section ids of the page and the <kbd> option texts inside each (innermost section first)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []  # open sections' ids ("" for a section without one)
        self.depth: list[str] = []  # every open element, to close sections correctly
        self.ids: set[str] = set()
        self.kbd: list[tuple[tuple[str, ...], str]] = []  # (enclosing section ids, text)
        self._in_kbd: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag in ("br", "img", "hr", "meta", "link", "input", "wbr"):
            return
        self.depth.append(tag)
        if tag == "section":
            ident = dict(attrs).get("id", "")
            self.stack.append(ident)
            self.ids.add(ident)
        if tag == "kbd":
            self._in_kbd = []

    def handle_endtag(self, tag):
        if tag not in self.depth:
            return
        while self.depth:
            open_tag = self.depth.pop()
            if open_tag == "section":
                self.stack.pop()
            if open_tag == tag:
                break
        if tag == "kbd" and self._in_kbd is not None:
            self.kbd.append((tuple(self.stack), "".join(self._in_kbd)))
            self._in_kbd = None

    def handle_data(self, data):
        if self._in_kbd is not None:
            self._in_kbd.append(data)


def section_id(path: tuple[str, ...]) -> str:
    return "-".join(("wearbench", *path))


@pytest.fixture(scope="module")
def reference(docs_html) -> _Reference:
    page = _Reference()
    page.feed((docs_html / "reference" / "cli.html").read_text(encoding="utf-8"))
    return page


@pytest.fixture(scope="module")
def commands() -> dict[tuple[str, ...], set[str]]:
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("COLUMNS", "250")  # argparse wraps at the terminal's width: one invocation per line
        return program_commands()


def test_the_help_is_read_as_a_user_reads_it(commands):
    """The parse of the help is itself right: it finds the commands and options everyone knows."""
    assert {("record",), ("identify",), ("estimate",), ("track",), ("bench",), ("bench", "check")} <= set(commands)
    assert len([p for p in commands if len(p) == 1]) >= 18
    assert {"--out", "-o", "--cycles", "--duration", "--backend", "--option", "--live"} <= commands[("record",)]
    assert "--version" in commands[()]


def test_every_subcommand_has_its_section(commands, reference):
    missing = [" ".join(("wearbench", *p)) for p in commands if p and section_id(p) not in reference.ids]
    assert not missing, f"subcommands the CLI reference does not list: {missing}"


def differences(commands, reference) -> tuple[dict, dict]:
    """(options the page does not list, options the page lists that the program lacks), by command."""
    command_ids = {section_id(p): p for p in commands if p}
    listed: dict[tuple[str, ...], set[str]] = {p: set() for p in commands}
    for enclosing, text in reference.kbd:
        owner = next((command_ids[s] for s in reversed(enclosing) if s in command_ids), ())
        listed[owner] |= set(OPTION.findall(text))
    missing = {" ".join(("wearbench", *p)): sorted(options - listed[p]) for p, options in commands.items()
               if options - listed[p]}
    extra = {" ".join(("wearbench", *p)): sorted(listed[p] - options - HELP) for p, options in commands.items()
             if listed[p] - options - HELP}
    return missing, extra


def test_every_option_is_listed_under_its_own_command(commands, reference):
    missing, extra = differences(commands, reference)
    assert not missing, f"options of `wearbench --help` the CLI reference does not list: {missing}"
    assert not extra, f"options on the CLI reference that the program does not have: {extra}"


def test_the_comparison_sees_a_missing_and_a_misplaced_option(commands, reference):
    """The comparison's own case: the page without record's --live, and with estimate's --estimator
    listed under record instead, is caught both ways."""
    doctored = _Reference()
    doctored.ids = set(reference.ids)
    for enclosing, text in reference.kbd:
        if text == "--live" and section_id(("record",)) in enclosing:
            continue
        if text == "--estimator" and section_id(("estimate",)) in enclosing:
            enclosing = (*enclosing[:-2], section_id(("record",)), "wearbench-record-named-arguments")
        doctored.kbd.append((enclosing, text))
    missing, extra = differences(commands, doctored)
    assert "--live" in missing["wearbench record"] and "--estimator" in missing["wearbench estimate"]
    assert extra == {"wearbench record": ["--estimator"]}
