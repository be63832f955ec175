"""`wearbench wear`: placeholder until its issue lands (see 'issues')."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("wear", help="(not built yet)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise RuntimeError("'wearbench wear' is not built yet")
