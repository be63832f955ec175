"""The ``wearbench`` command line: one entry point, one module per subcommand in this package.

Each subcommand module defines ``register(subparsers)`` which adds its parser and sets
``func(args) -> int``. Modules are imported lazily by name so ``wearbench --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from importlib.metadata import version

__all__ = ["COMMANDS", "main"]

# subcommand -> module in wearbench.cli
COMMANDS: dict[str, str] = {
    "bench": "bench",
    "simulate": "simulate",
    "wear": "wear",
    "study": "study",
    "sweep": "sweep",
    "record": "record",
    "inspect": "inspect",
    "recover": "recover",
    "emulate": "emulate",
    "compare": "compare",
    "identify": "identify",
    "ensemble": "ensemble",
    "demo": "demo",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="wearbench",
        description="Mechanism test beds with worn revolute clearance joints: record bench sessions to "
        "MCAP, simulate the multibody theory, and score measurement against theory.",
        epilog="Quantities take units: 0.6mm, -5pi (rad/s), 300rpm, 1Hz. Run 'wearbench demo' for the "
        "whole toolkit on the built-in simulated bench; 'wearbench COMMAND --help' for each command.",
    )
    parser.add_argument("--version", action="version", version=f"wearbench {version('wearbench')}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS.values():
        importlib.import_module(f"wearbench.cli.{module}").register(sub)
    _allow_negative_values(parser)
    return parser


def _allow_negative_values(parser: argparse.ArgumentParser) -> None:
    """Let option values that look like negative quantities through as values (``--speed -2pi``,
    ``--t-end -1s``): argparse takes only plain negative numbers as values. No wearbench option
    looks like a negative number, so nothing is lost."""
    parser._negative_number_matcher = re.compile(r"^-(\d|\.\d|pi|π)")
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _allow_negative_values(child)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("wearbench: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, RuntimeError) as exc:  # errors meant for the user: one clear line
        print(f"wearbench {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
